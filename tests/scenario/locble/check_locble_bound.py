#!/usr/bin/env python3
"""Checks tools/scripts/locble_bound.py (docs/locble.md "The bound"), the figure the issue-17 bars are
judged against, so it must be right:
  1. its Jacobian against finite differences of its own RSS model;
  2. the bound against a Monte Carlo of an efficient estimator: MAP (Gauss-Newton with the same priors,
     started at the truth: the estimator's local statistics, not its search) on readings drawn from the
     model (offsets from their priors, exponents at the linearisation point), a tag near an L walk: its
     position rms must match the bound (0.9-1.1x) — a wrong information matrix, prior or Schur
     complement shows here;
  3. on a simulated scene (`locus simulate locble`): every bound finite and positive, fewer unknowns
     (--known-model) never worse, less fading never worse, fusing a cluster never worse;
  4. with the foreign locble-105 (when LOCUS_FOREIGN_SCENES names it), its documented 3.58 m.
usage: check_locble_bound.py LOCUS_BINARY SOURCE_DIR [FOREIGN_SCENES_DIR]
"""
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

locus, source = sys.argv[1], sys.argv[2]
foreign = sys.argv[3] if len(sys.argv) > 3 else ''
sys.path.insert(0, os.path.join(source, 'tools', 'scripts'))
import locble_bound as LB  # noqa: E402

sys.path.insert(0, os.path.join(source, 'tests', 'scenario'))
from scenario_checks import Checks  # noqa: E402

check = Checks()


# An L walk: 3.5 m along +x, then 3.5 m along +y; readings every 0.05 s over 14 s.
rng = np.random.default_rng(17)
t = np.linspace(0.0, 14.0, 281)
s = np.clip(t / 14.0 * 7.0, 0.0, 7.0)
px = np.where(s < 3.5, s, 3.5)
py = np.where(s < 3.5, 0.0, s - 3.5)
env_index = (t > 7.0).astype(int)  # two classes: the environment changes halfway
m = 2

# 1. Jacobian.
theta = np.array([2.0, 3.0, -1.0, 0.5, -2.0, 2.2, 2.8])
g = LB.jacobian(theta, px, py, env_index, m)
fd = np.zeros_like(g)
for k in range(len(theta)):
    h = np.zeros_like(theta)
    h[k] = 1e-6
    fd[:, k] = (LB.mean_rss(theta + h, px, py, env_index, m) - LB.mean_rss(theta - h, px, py, env_index, m)) / 2e-6
check(np.max(np.abs(g - fd)) < 1e-5, f'jacobian matches finite differences (max diff {np.max(np.abs(g - fd)):.2e})')

# 2. Monte Carlo of the MAP estimator. Noise: fading 1.5 dB, shadowing 0.8 dB over 2.5 m, channel
# offsets 1 dB on three channels; priors as the script's; the true offsets drawn from them, the
# exponents at the prior's mean (where the bound is linearised; drawn too, the rms is 1.12x: the
# information grows with n^2).
a = LB.defaults(fading_db=1.5, shadowing_db=0.8, channel_db=1.0)
tag = np.array([2.0, 3.0])
channel = np.array(['37', '38', '39'])[np.arange(len(t)) % 3]
readings = [{'t_true': float(tk), 'env': 'AB'[e], 'channel': c} for tk, e, c in zip(t, env_index, channel)]
path = np.stack([t, px, py], 1)
info, _, _ = LB.position_information(path, tag, readings, a)
bound = LB.rms_bound(info, a)
walk = np.hypot(px[:, None] - px[None, :], py[:, None] - py[None, :])
same = env_index[:, None] == env_index[None, :]
cov = (a.fading_db ** 2 * np.eye(len(t)) + a.shadowing_db ** 2 * np.exp(-walk / a.decorrelation_m) * same
       + a.channel_db ** 2 * (channel[:, None] == channel[None, :]))
chol = np.linalg.cholesky(cov)
cov_inv = np.linalg.inv(cov)
prior_mean = np.concatenate([[0.0, 0.0, 0.0], np.zeros(m), np.full(m, a.n)])
prior_info = np.diag([a.position_sd_m ** -2] * 2 + [a.common_db ** -2] + [a.link_db ** -2] * m + [a.n_sd ** -2] * m)
errors = []
for trial in range(400):
    nuis = np.concatenate([[rng.normal(0.0, a.common_db)], rng.normal(0.0, a.link_db, m), np.full(m, a.n)])
    truth = np.concatenate([tag, nuis])
    y = LB.mean_rss(truth, px, py, env_index, m) + chol @ rng.standard_normal(len(t))
    est = truth.copy()
    for _ in range(30):  # Gauss-Newton on the posterior (readings + the priors)
        r = y - LB.mean_rss(est, px, py, env_index, m)
        J = LB.jacobian(est, px, py, env_index, m)
        H = J.T @ cov_inv @ J + prior_info
        step = np.linalg.solve(H, J.T @ cov_inv @ r - prior_info @ (est - prior_mean))
        est = est + step
        if np.max(np.abs(step)) < 1e-9:
            break
    errors.append(est[:2] - tag)
rms = math.sqrt(np.mean(np.sum(np.square(errors), 1)))
check(0.9 <= rms / bound <= 1.1, f'MAP estimator rms {rms:.3f} m vs bound {bound:.3f} m (ratio {rms / bound:.2f}, 400 draws)')

# 3. A simulated scene.
with tempfile.TemporaryDirectory() as work:
    scene = os.path.join(work, 's2')
    subprocess.run([locus, 'simulate', 'locble', scene, '--seed', '2', '-q', '-o', 'tags=4', '-o', 'clustered=2'],
                   check=True)
    base = LB.run_rows(LB.defaults(scenes=[scene], cluster_radius_m=1.5))
    known = LB.run_rows(LB.defaults(scenes=[scene], known_model=True))
    calm = LB.run_rows(LB.defaults(scenes=[scene], fading_db=2.0))
    check(len(base) == 4, f'{len(base)} tags bounded (4 simulated)')
    check(all(0.0 < r['bound_rms_m'] < 50.0 for r in base), 'every bound finite and positive')
    check(all(k['bound_rms_m'] <= b['bound_rms_m'] + 1e-9 for k, b in zip(known, base)),
          'one environment class (fewer unknowns) never raises the bound')
    check(all(c['bound_rms_m'] <= b['bound_rms_m'] + 1e-9 for c, b in zip(calm, base)), 'less fading never raises it')
    check(all(r['fused_bound_rms_m'] <= r['bound_rms_m'] + 1e-9 for r in base), 'fusing a cluster never raises it')
    check(any(r['cluster_size'] > 1 and r['fused_bound_rms_m'] < 0.9 * r['bound_rms_m'] for r in base),
          'a clustered tag gains from fusion')

# 4. The foreign scene's documented figure.
lb105 = os.path.join(foreign, 'locble-105')
if foreign and os.path.isdir(lb105):
    rows = LB.run_rows(LB.defaults(scenes=[lb105]))
    mean = float(np.mean([r['bound_mean_m'] for r in rows]))
    check(abs(mean - 3.58) < 0.02, f'locble-105: mean-equivalent bound {mean:.2f} m (docs/locble.md: 3.58 m)')
else:
    print('skip locble-105 (no foreign scenes)')

check.finish()
