#!/usr/bin/env python3
"""AMIL accuracy campaign (docs/amil.md, "Accuracy"): simulate -> detect -> solve -> score, many seeds.

Two paths, on the same scenes:
  solver   the positioning methods of plugins/amil/solver.hpp on the chirp detector's arrivals
           (`locus replay SCENE -c config/replay-chirp-amil.yaml --events audio_detection`, truth-free
           beep pairing) and the player's TRUE speaker positions in its start frame, optionally with
           Gaussian position noise (--position-noise-m) standing in for IMU tracking error. This
           isolates the solver (and the detector) from the IMU tracker; `locus_amil_solve` runs every
           method on identical inputs. Truth is used only for the beep positions and for scoring.
  plugin   the whole localizer: `locus replay SCENE -c config/amil.yaml` then
           `locus eval SCENE EST --metric amil --json` (with --plugin-config; any method via
           --plugin-method, which writes a temporary copy of the config).

usage: amil_campaign.py --locus BIN --solve BIN [--seeds 1-20] [--difficulty normal] [--gestures 1]
                        [--work /tmp/amil-campaign] [--position-noise-m 0,0.002,0.005]
                        [--plugin-config config/amil.yaml] [--plugin-method robust,paper] [--json OUT]
Pure python3 (json, csv, yaml). Prints markdown tables.
"""
import argparse, csv, json, math, os, random, subprocess, sys, statistics

import yaml


def parse_seeds(s):
    out = []
    for part in s.split(','):
        if '-' in part:
            a, b = part.split('-')
            out += list(range(int(a), int(b) + 1))
        else:
            out.append(int(part))
    return out


def run(cmd, **kw):
    r = subprocess.run(cmd, capture_output=True, text=True, **kw)
    if r.returncode not in (0, 4):
        sys.exit(f"amil_campaign: {' '.join(cmd)} failed ({r.returncode}):\n{r.stderr[-2000:]}")
    return r


# ------------------------------------------------------------------------------------------ geometry
def quat_rot(q, v):
    w, x, y, z = q
    R = [[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
         [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
         [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]]
    return [sum(R[i][j] * v[j] for j in range(3)) for i in range(3)]


class Truth:
    def __init__(self, scene):
        self.S = yaml.safe_load(open(f"{scene}/scene.yaml"))
        self.tr = {}
        for row in csv.DictReader(open(f"{scene}/truth.csv")):
            self.tr.setdefault(row['id'], []).append([float(row[k]) for k in 't x y z qw qx qy qz'.split()])
        self.em = [(float(r['t_true']), r['id']) for r in csv.DictReader(open(f"{scene}/truth_emissions.csv"))]
        self.fs = self.S['sample_rate']
        self.c = self.S['speed_of_sound']
        self.clocks = self.S['truth']['clocks']

    def pose(self, i, t):
        a = self.tr[i]
        if len(a) == 1 or t <= a[0][0]:
            r = a[0]
        elif t >= a[-1][0]:
            r = a[-1]
        else:
            lo, hi = 0, len(a) - 1
            while hi - lo > 1:
                mid = (lo + hi) // 2
                if a[mid][0] <= t: lo = mid
                else: hi = mid
            f = (t - a[lo][0]) / (a[hi][0] - a[lo][0])
            r = [a[lo][k] + f * (a[hi][k] - a[lo][k]) for k in range(8)]
        q = r[4:8]
        n = math.sqrt(sum(x * x for x in q))
        return r[1:4], [x / n for x in q]

    def start_frame(self, ref):
        p0, q0 = self.pose(ref, self.tr[ref][0][0])
        by = quat_rot(q0, [0, 1, 0])
        n = math.hypot(by[0], by[1])
        yax = [by[0] / n, by[1] / n]
        xax = [yax[1], -yax[0]]  # x = y × z
        return p0, xax, yax

    def to_frame(self, frame, p):
        p0, xax, yax = frame
        d = [p[0] - p0[0], p[1] - p0[1]]
        return [d[0] * xax[0] + d[1] * xax[1], d[0] * yax[0] + d[1] * yax[1]]

    def skew(self, dev):
        return self.clocks.get(dev, {}).get('skew_ppm', 0.0) * 1e-6


# ------------------------------------------------------------------------------------------ pairing
def pair(player_t, listener_t, tol=0.02):
    """Truth-free: the listener arrival of each player beep (or None), by the best common offset."""
    best = (0, [None] * len(player_t))
    for a in listener_t:
        for e in player_t:
            off = a - e
            m = []
            for ek in player_t:
                cand = [x for x in listener_t if abs(x - ek - off) < tol]
                m.append(min(cand, key=lambda x: abs(x - ek - off)) if cand else None)
            n = sum(x is not None for x in m)
            if n > best[0]:
                best = (n, m)
    return best[1]


def build_problem(scene, det_file, sigma_p, rng, calibrated):
    T = Truth(scene)
    S = T.S
    player = next(d['id'] for d in S['devices'] if d.get('emits'))
    spk = next(d for d in S['devices'] if d['id'] == player).get('speaker', [0, 0, 0])
    dets = {}
    for line in open(det_file):
        d = json.loads(line)
        if d.get('type') != 'audio_detection': continue
        dets.setdefault(d['device'], []).append(d['frame'] / d['sample_rate_hz'])
    for v in dets.values(): v.sort()
    e = dets.get(player, [])
    frame = T.start_frame(player)
    em = sorted(t for t, src in T.em if src == player)
    # pair the player's own detections with the true emissions (truth only for the positions)
    beeps = []
    ck = T.clocks.get(player, {'offset_s': 0, 'skew_ppm': 0})
    for t_true in em:
        local = t_true * (1 + ck['skew_ppm'] * 1e-6) + ck['offset_s']
        cand = [x for x in e if abs(x - local) < 0.03]
        p, q = T.pose(player, t_true)
        s = quat_rot(q, spk)
        pf = T.to_frame(frame, [p[0] + s[0], p[1] + s[1]])
        pf = [pf[0] + rng.gauss(0, sigma_p), pf[1] + rng.gauss(0, sigma_p)] if sigma_p > 0 else pf
        beeps.append({'p': pf, 'e': min(cand, key=lambda x: abs(x - local)) if cand else None})
    ev = [b['e'] for b in beeps if b['e'] is not None]
    listeners, truth = [], {}
    for d in S['devices']:
        lid = d['id']
        if lid == player: continue
        a = pair(ev, dets.get(lid, []))
        amap = dict(zip(ev, a))
        arr = [amap.get(b['e']) if b['e'] is not None else None for b in beeps]
        L = {'id': lid, 'a': arr}
        if calibrated: L['known_skew'] = (1 + T.skew(lid)) / (1 + T.skew(player)) - 1
        listeners.append(L)
        pl, _ = T.pose(lid, T.tr[lid][0][0])
        truth[lid] = T.to_frame(frame, pl)
    return {'c': T.c, 'timing_std_s': 1.5e-6, 'position_std_m': max(sigma_p, 0.001), 'beeps': beeps,
            'listeners': listeners}, truth


# ------------------------------------------------------------------------------------------ scoring
def score(rows, truth):
    """rows: solver outputs of one method over many scenes; truth: {(name, id): (x, y)}."""
    dirs, pct_near, pos, located, n = [], [], [], 0, 0
    for r in rows:
        tx, ty = truth[(r['name'], r['id'])]
        n += 1
        td = math.hypot(tx, ty)
        if r['direction_rad'] is not None:
            located += 1
            dirs.append(abs(math.remainder(r['direction_rad'] - math.atan2(ty, tx), 2 * math.pi)) * 180 / math.pi)
        if r['x'] is not None:
            pos.append(math.hypot(r['x'] - tx, r['y'] - ty))
            if td <= 2.5: pct_near.append(100 * abs(r['distance_m'] - td) / td)
    f = lambda v, g: (g(v) if v else float('nan'))
    return {'n': n, 'located_fraction': located / n if n else float('nan'),
            'with_position_fraction': len(pos) / n if n else float('nan'),
            'mean_direction_error_deg': f(dirs, statistics.mean),
            'p90_direction_error_deg': f(sorted(dirs), lambda v: v[int(0.9 * (len(v) - 1))]),
            'median_distance_error_pct_within_2_5m': f(pct_near, statistics.median),
            'mean_position_error_m': f(pos, statistics.mean),
            'median_position_error_m': f(pos, statistics.median)}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--locus', required=True)
    ap.add_argument('--solve', help='locus_amil_solve binary (solver path)')
    ap.add_argument('--seeds', default='1-20')
    ap.add_argument('--difficulty', default='normal')
    ap.add_argument('--gestures', type=int, default=1)
    ap.add_argument('--work', default='/tmp/amil-campaign')
    ap.add_argument('--position-noise-m', default='0')
    ap.add_argument('--plugin-config')
    ap.add_argument('--plugin-method', default='')
    ap.add_argument('--json')
    ap.add_argument('--scenes', default='', help='comma-separated existing scene dirs (e.g. ../shared/scenes/amil-101) '
                    'instead of simulating --seeds (plugin path only)')
    ap.add_argument('--repo', default=os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
    args = ap.parse_args()
    seeds = parse_seeds(args.seeds)
    os.makedirs(args.work, exist_ok=True)
    det_cfg = os.path.join(args.repo, 'config', 'replay-chirp-amil.yaml')
    results = {'args': vars(args), 'solver': {}, 'plugin': {}}
    scenes = [os.path.abspath(x) for x in args.scenes.split(',') if x]
    for seed in ([] if scenes else seeds):
        sc = os.path.join(args.work, f"{args.difficulty}-g{args.gestures}-s{seed}")
        if not os.path.exists(os.path.join(sc, 'truth.csv')):
            run([args.locus, 'simulate', 'amil', sc, '--seed', str(seed), '--difficulty', args.difficulty,
                 '-o', f'gestures={args.gestures}'])
        scenes.append(sc)
    if args.solve:
        for sc in scenes:
            det = sc + '.det.jsonl'
            if not os.path.exists(det):
                run([args.locus, 'replay', sc, '-c', det_cfg, '--speed', 'max', '--events', 'audio_detection', '-o', det])
        for sp in [float(x) for x in args.position_noise_m.split(',')]:
            for calibrated in (False, True):
                rng = random.Random(12345)
                probs, truth = [], {}
                for sc in scenes:
                    p, t = build_problem(sc, sc + '.det.jsonl', sp, rng, calibrated)
                    p['name'] = sc
                    probs.append(json.dumps(p))
                    truth.update({(sc, k): v for k, v in t.items()})
                out = run([args.solve], input='\n'.join(probs) + '\n').stdout
                rows = [json.loads(l) for l in out.splitlines() if l.strip()]
                methods = ['paper'] if calibrated else ['paper', 'paper_joint_skew', 'joint', 'robust', 'network']
                for m in methods:
                    key = f"sigma_p={sp}|{m}{' (true skew given)' if calibrated else ''}"
                    results['solver'][key] = score([r for r in rows if r['method'] == m], truth)
        print(f"\n### Solver on detector arrivals + true beep positions (+ noise): {args.difficulty}, "
              f"{args.gestures} gesture(s), seeds {args.seeds}\n")
        print("| beep position noise | method | located | with position | mean dir err (deg) | p90 dir err (deg) "
              "| median dist err <=2.5 m (%) | mean pos err (m) | median pos err (m) |")
        print("|---|---|---|---|---|---|---|---|---|")
        for k, s in results['solver'].items():
            sp, m = k.split('|')
            print(f"| {sp.split('=')[1]} m | {m} | {s['located_fraction']:.2f} | {s['with_position_fraction']:.2f} | "
                  f"{s['mean_direction_error_deg']:.2f} | {s['p90_direction_error_deg']:.2f} | "
                  f"{s['median_distance_error_pct_within_2_5m']:.1f} | {s['mean_position_error_m']:.3f} | "
                  f"{s['median_position_error_m']:.3f} |")
    if args.plugin_config:
        methods = [m for m in args.plugin_method.split(',') if m] or [None]
        print(f"\n### Plugin end to end (locus replay -c {os.path.basename(args.plugin_config)} + locus eval --metric amil): "
              f"{args.difficulty}, {args.gestures} gesture(s), seeds {args.seeds}\n")
        print("| method | scenes | listeners located | mean dir err (deg) | worst scene's mean dir err | median dist err "
              "<= 2.5 m (%) (n) | within 2.5 m with distance | mean pos err (m) | median pos err (m) | with position "
              "| std coverage 1σ / 2σ (pos) | dist 1σ / 2σ | dir 1σ / 2σ | flagged (mean dir err) | unflagged mean dir err |")
        print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
        for m in methods:
            cfg = args.plugin_config
            if m:
                C = yaml.safe_load(open(args.plugin_config))
                for loc in C.get('localizers', []):
                    if loc.get('plugin') == 'amil': loc.setdefault('params', {})['method'] = m
                cfg = os.path.join(args.work, f"amil-{m}.yaml")
                yaml.safe_dump(C, open(cfg, 'w'))
            summ, near, dirs, located, expected, pos = [], [], [], 0, 0, []
            cov = {'pos': [], 'dist': [], 'dir': []}   # error / std per estimate
            near_total, flagged_dirs, unflagged_dirs = 0, [], []
            for sc in scenes:
                est = f"{sc}.{m or 'default'}.est.jsonl"
                run([args.locus, 'replay', sc, '-c', cfg, '--speed', 'max', '-o', est])
                r = run([args.locus, 'eval', sc, est, '--metric', 'amil', '--json'])
                J = json.loads(r.stdout)
                pl = J['plugins'][0] if J.get('plugins') else {'summary': {}, 'targets': []}
                summ.append(pl['summary'])
                expected += pl['summary'].get('targets_expected') or 0
                located += pl['summary'].get('targets_located') or 0
                ests = {}
                for line in open(est):
                    e = json.loads(line)
                    if e.get('type') == 'estimate': ests[e['target']] = e
                for t in pl.get('targets', []):
                    e = ests.get(t.get('target'), {})
                    if (t.get('true_distance_m') or 99) <= 2.5: near_total += 1
                    if t.get('direction_error_deg') is not None:
                        (flagged_dirs if {'inconsistent', 'weak'} & set(e.get('flags') or []) else unflagged_dirs).append(t['direction_error_deg'])
                    if e.get('std_m') and t.get('position_error_m') is not None:
                        cov['pos'].append(t['position_error_m'] / e['std_m'])
                    if e.get('distance_std_m') and t.get('distance_error_pct') is not None and t.get('true_distance_m'):
                        cov['dist'].append(abs(t['distance_error_pct']) / 100 * t['true_distance_m'] / e['distance_std_m'])
                    if e.get('direction_std_rad') and t.get('direction_error_deg') is not None:
                        cov['dir'].append(math.radians(abs(t['direction_error_deg'])) / e['direction_std_rad'])
                    if t.get('direction_error_deg') is not None: dirs.append(t['direction_error_deg'])
                    if t.get('position_error_m') is not None: pos.append(t['position_error_m'])
                    if (t.get('true_distance_m') or 99) <= 2.5 and t.get('distance_error_pct') is not None:
                        near.append(t['distance_error_pct'])
            g = lambda k: [s[k] for s in summ if s.get(k) is not None]
            mean = lambda v: statistics.mean(v) if v else float('nan')
            med = lambda v: statistics.median(v) if v else float('nan')
            results['plugin'][m or 'default'] = {'per_seed': summ, 'pooled': {
                'located_fraction': located / expected if expected else None, 'mean_direction_error_deg': mean(dirs),
                'median_distance_error_pct_within_2_5m': med(near), 'listeners_within_2_5m_with_distance': len(near),
                'mean_position_error_m': mean(pos), 'median_position_error_m': med(pos)}}
            c12 = lambda v: (f"{sum(1 for x in v if x <= 1) / len(v) * 100:.0f} / {sum(1 for x in v if x <= 2) / len(v) * 100:.0f} % "
                             f"({len(v)})") if v else "-"
            results['plugin'][m or 'default']['pooled'].update({
                'coverage': {k: [sum(1 for x in v if x <= 1) / len(v) if v else None,
                                 sum(1 for x in v if x <= 2) / len(v) if v else None, len(v)] for k, v in cov.items()},
                'flagged': len(flagged_dirs), 'flagged_mean_direction_error_deg': mean(flagged_dirs),
                'unflagged_mean_direction_error_deg': mean(unflagged_dirs), 'listeners_within_2_5m': near_total})
            print(f"| {m or 'config'} | {len(summ)} | {located}/{expected} | {mean(dirs):.2f} | "
                  f"{max(g('mean_direction_error_deg') or [float('nan')]):.2f} | {med(near):.1f} ({len(near)}) | "
                  f"{len(near)}/{near_total} | {mean(pos):.3f} | {med(pos):.3f} | {len(pos)} | {c12(cov['pos'])} | "
                  f"{c12(cov['dist'])} | {c12(cov['dir'])} | {len(flagged_dirs)} ({mean(flagged_dirs):.1f}) | "
                  f"{mean(unflagged_dirs):.2f} |")
    if args.json:
        json.dump(results, open(args.json, 'w'), indent=1, default=str)


if __name__ == '__main__':
    main()
