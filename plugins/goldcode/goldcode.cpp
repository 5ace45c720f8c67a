// The `goldcode` detector: Montage's multi-user Gold-code receiver; algorithm in goldcode.hpp.
#include "goldcode.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <complex>
#include <cstdint>
#include <cstring>
#include <memory>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "locus/dsp/emission_canceller.hpp"
#include "locus/dsp/fir.hpp"
#include "locus/dsp/iir.hpp"
#include "locus/dsp/signals.hpp"
#include "locus/dsp/simd.hpp"
#include "locus/fftw_planner.hpp"
#include "locus/numbers.hpp"

namespace locus::plugins::goldcode {

namespace {

using cf = std::complex<float>;
using cd = std::complex<double>;

struct CodeTemplate {
  std::vector<float> cc_re, cc_im;  // conj(DFT) of the zero-padded, mean-removed complex baseband template (split)
  double energy = 0.0;              // Σ|T − T̄|²
  std::vector<float> full_i, full_q;  // full-rate band-passed template, both quadratures
  double full_energy = 0.0;         // Σ full_i² (≈ Σ full_q²)
};

struct Peak {
  std::int64_t lag = 0;  // decimated index (absolute: frame = lag·D)
  double rho = 0.0, rho_prev = -1.0, rho_next = -1.0;
  bool have_next = false;
  std::uint16_t dop = 0;  // Doppler bin of the best version at this lag
};

// Local maxima of one code's ρ inside one code length: a weak user's true peak can be lower than
// a stronger user's cross-correlation sidelobe nearby, so several are kept and the joint refinement
// decides.
struct Candidate {
  static constexpr int kMaxPeaks = 8;
  bool open = false;
  std::int64_t lag = 0;  // best peak so far (used by the other codes' joint refinements)
  double rho = 0.0;
  std::uint16_t dop = 0; // its Doppler bin
  double noise = 0.0;    // mean ρ² of the code over the hop
  std::int64_t first_lag = 0;
  Peak peaks[kMaxPeaks];
  int npeaks = 0;
  bool in_run = false;   // inside a run of lags above the thresholds
  Peak cur;              // the run's maximum
  std::int64_t last_above = 0;
};

// One code taking part in a joint refinement.
struct Member {
  std::size_t code;
  double frame;    // current arrival estimate
  double ci, cq;   // in-phase / quadrature amplitude (y ≈ ci·g_i + cq·g_q at the integer delay)
  double rho;
  bool known;      // refined before (a final detection), ci/cq valid
  double rho_fine = 0.0;  // Pearson of the residual with the template at the refined lag
  std::int64_t at = 0;    // integer frame at which ci·g_i + cq·g_q is subtracted from the residual
  std::size_t dop = 0;    // Doppler bin of the template version
};

using dsp::simd::v4f;  // GCC/Clang vectors: SSE on x86-64, NEON on the Pi
namespace simd = dsp::simd;

// The anti-alias low-pass and decimation of the I and Q streams in one pass (the same arithmetic
// as dsp::FirDecimator, which filters the templates offline: Σ taps[k]·x[oldest + k], outputs only
// on the decimation grid), with the taps zero-padded in front to a multiple of 4 and 4-lane sums.
struct IqDecimator {
  std::vector<float> taps;   // padded length L (multiple of 4), leading zeros
  std::vector<float> hi, hq; // 2L history, doubled so that the window is contiguous
  std::size_t len = 0, pos = 0, factor = 1, phase = 0;

  IqDecimator() = default;
  IqDecimator(const std::vector<double>& t, std::size_t d) : factor(d) {
    len = (t.size() + 3) / 4 * 4;
    taps.assign(len, 0.0f);
    for (std::size_t k = 0; k < t.size(); ++k) taps[len - t.size() + k] = static_cast<float>(t[k]);
    hi.assign(2 * len, 0.0f);
    hq.assign(2 * len, 0.0f);
  }
  void reset() noexcept {
    std::fill(hi.begin(), hi.end(), 0.0f);
    std::fill(hq.begin(), hq.end(), 0.0f);
    pos = 0;
    phase = 0;
  }
  void set_next_output(std::size_t k) noexcept { phase = (factor - k % factor) % factor; }
  std::size_t process(const float* xi, const float* xq, std::size_t n, float* oi, float* oq) noexcept {
    std::size_t produced = 0;
    for (std::size_t i = 0; i < n; ++i) {
      hi[pos] = hi[pos + len] = xi[i];
      hq[pos] = hq[pos + len] = xq[i];
      pos = pos + 1 == len ? 0 : pos + 1;
      if (phase == 0) {
        const float* a = hi.data() + pos;
        const float* b = hq.data() + pos;
        v4f si = {}, sq = {};
        for (std::size_t k = 0; k < len; k += 4) {
          v4f tk, ak, bk;
          std::memcpy(&tk, taps.data() + k, sizeof tk);
          std::memcpy(&ak, a + k, sizeof ak);
          std::memcpy(&bk, b + k, sizeof bk);
          si += tk * ak;
          sq += tk * bk;
        }
        oi[produced] = (si[0] + si[1]) + (si[2] + si[3]);
        oq[produced] = (sq[0] + sq[1]) + (sq[2] + sq[3]);
        ++produced;
      }
      phase = phase + 1 == factor ? 0 : phase + 1;
    }
    return produced;
  }
};

struct Channel {
  dsp::SosFilter bpf;
  IqDecimator dec;
  cd osc{1.0, 0.0};
  std::vector<float> ring;          // band-passed full-rate signal, indexed by frame & mask
  std::vector<float> xi, xq;        // overlap-save buffers (Nfft decimated samples)
  std::size_t fill = 0;
  std::int64_t base = 0;            // decimated index of xi[0]
  std::vector<Candidate> cand;      // per code
  std::vector<std::int64_t> last_final;  // per code: lag of the last emitted detection
  std::vector<double> last_rho;     // per code: ρ of the previous lag (across hops)
  std::vector<double> fin_frame, fin_ci, fin_cq;  // per code: the last final detection's estimate
  std::vector<std::size_t> fin_dop;               // ... and its Doppler bin
  std::vector<AudioDetection> pend;               // per code: the detection waiting for its separation
  std::vector<std::size_t> pend_dop;
  std::vector<std::uint8_t> has_pend;
  // Round gate (round_window_s): the own emissions' fitted starts, newest last (a ring of kOwnKept).
  static constexpr std::size_t kOwnKept = 8;
  double own_frames[kOwnKept] = {};
  std::size_t own_count = 0;
  double own_known_until = 0.0;  // every own emission starting before this frame is in own_frames
  std::uint64_t end_frame = 0;      // one past the last frame written to `ring`
  double level = 0.0;               // slow average of the window energy (guards near-silent windows)
  bool started = false;
  std::int64_t grid_start = 0;      // first decimated index with valid data since the last reset
  std::uint64_t start_frame = 0;    // first frame with valid data (ring validity)
};

// Hilbert transform (FFT, zero-padded to twice the length so the circular wrap stays outside) [main].
std::vector<float> hilbert(const std::vector<float>& x, FftPlanner& planner) {
  const std::size_t n = std::bit_ceil(2 * x.size());
  auto fft = planner.plan_real(n);
  std::vector<float> buf(n, 0.0f), out(n);
  std::copy(x.begin(), x.end(), buf.begin());
  std::vector<cf> spec(n / 2 + 1);
  fft->forward(buf.data(), spec.data());
  spec[0] = 0.0f;
  spec[n / 2] = 0.0f;
  for (std::size_t k = 1; k < n / 2; ++k) spec[k] *= cf(0.0f, -1.0f);
  fft->inverse(spec.data(), out.data());
  std::vector<float> h(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) h[i] = out[i] / static_cast<float>(n);
  return h;
}

// The gold signal of `spec` as received from a source closing in at relative speed v: time-compressed
// by alpha = 1 + v/c (carrier and chip rate both scaled), s_alpha[n] = a·c[floor(alpha·n / chip)]·
// cos(2π·carrier·alpha·n/fs); alpha = 1 is exactly the format's signal [main].
std::vector<float> render_scaled(const dsp::SignalSpec& spec, double fs, double alpha) {
  (void)dsp::render_signal(spec, fs);  // validates the spec (clear errors)
  const std::vector<std::uint8_t> chips = dsp::gold_chips(spec);
  const double cs = static_cast<double>(spec.chip_samples);
  const double len = static_cast<double>(chips.size()) * cs;
  const std::size_t n_out = static_cast<std::size_t>(std::ceil(len / alpha));
  std::vector<float> s(n_out, 0.0f);
  for (std::size_t n = 0; n < n_out; ++n) {
    const double u = alpha * static_cast<double>(n);
    const std::size_t k = static_cast<std::size_t>(u / cs);
    if (k >= chips.size()) break;
    const double ph = 2.0 * kPi * std::fmod(spec.carrier_hz * u / fs, 1.0);
    s[n] = static_cast<float>(spec.amplitude * (chips[k] ? -1.0 : 1.0) * std::cos(ph));
  }
  return s;
}

class GoldcodeDetector final : public Detector {
 public:
  void configure(const StreamInfo& info, const Params& params, HostContext& ctx) override {
    log_ = &ctx.log;
    device_ = info.device;
    detector_ = NameTag(ctx.instance);
    stream_ = info.stream;
    fs_ = info.sample_rate_hz;
    if (!(fs_ > 0)) throw std::runtime_error("goldcode: sample rate must be > 0");
    if (info.channels == 0) throw std::runtime_error("goldcode: the stream has no channels");
    channels_ = info.channels;
    max_block_ = info.max_block_frames;

    carrier_hz_ = params.get_float("carrier_hz");
    const int chip_samples = static_cast<int>(params.get_int("chip_samples"));
    const int degree = static_cast<int>(params.get_int("degree"));
    const double bw = params.get_float("band_width_hz");
    const int order = static_cast<int>(params.get_int("filter_order"));
    min_rho_ = params.get_float("min_pearson");
    min_rho_coarse_ = params.get_float("min_pearson_coarse");
    min_snr_db_ = params.get_float("min_snr_db");
    min_snr_lin_ = std::pow(10.0, min_snr_db_ / 10.0);
    const double amplitude = 1.0;
    std::int64_t dec = params.get_int("decimation");
    if (dec == 0) dec = std::max<std::int64_t>(1, static_cast<std::int64_t>(std::floor(fs_ / (1.6 * bw))));
    if (static_cast<double>(dec) * bw > fs_)
      throw std::runtime_error("goldcode: decimation " + std::to_string(dec) + " leaves a baseband rate of " +
                               std::to_string(fs_ / dec) + " Hz, below band_width_hz (" + std::to_string(bw) + " Hz)");
    D_ = static_cast<std::size_t>(dec);

    // The codes: the scene's Gold signals (scene order, `chips` authoritative) or family indices.
    specs_.clear();
    if (params.get_bool("from_scene")) {
      if (ctx.geometry == nullptr)
        throw std::runtime_error("goldcode: from_scene: true needs the scene's signals (replay of a scene), but the "
                                 "host gave no device geometry; list `codes` instead");
      for (const SceneSignal& e : ctx.geometry->scene_emits)
        if (e.signal.type == "gold") {
          dsp::SignalSpec spec = e.signal;
          spec.amplitude = amplitude;
          specs_.push_back(spec);
        }
      if (specs_.empty()) throw std::runtime_error("goldcode: from_scene: the scene emits no `gold` signal");
      for (const dsp::SignalSpec& sp : specs_)
        if (sp.carrier_hz != specs_[0].carrier_hz || sp.chip_samples != specs_[0].chip_samples)
          throw std::runtime_error("goldcode: from_scene: the scene's gold signals differ in carrier or chip_samples "
                                   "(one detector instance serves one carrier and chip rate)");
      carrier_hz_ = specs_[0].carrier_hz;
    } else {
      const std::vector<double>& codes = params.get_floats("codes");
      if (codes.empty()) throw std::runtime_error("goldcode: `codes` lists no code index");
      const int family = (1 << degree) + 1;
      for (double c : codes) {
        if (c != std::floor(c) || c < 0 || c >= family)
          throw std::runtime_error("goldcode: code index " + std::to_string(c) + " in `codes` is not an integer in 0.." +
                                   std::to_string(family - 1) + " (degree " + std::to_string(degree) + ")");
        dsp::SignalSpec spec;
        spec.type = "gold";
        spec.amplitude = amplitude;
        spec.degree = degree;
        spec.index = static_cast<int>(c);
        spec.carrier_hz = carrier_hz_;
        spec.chip_samples = chip_samples;
        specs_.push_back(spec);
      }
    }
    {
      const double lo2 = carrier_hz_ - bw / 2.0, hi2 = carrier_hz_ + bw / 2.0;
      if (!(lo2 > 0.0) || !(hi2 < fs_ / 2.0))
        throw std::runtime_error("goldcode: carrier ± band_width_hz/2 = [" + std::to_string(lo2) + ", " +
                                 std::to_string(hi2) + "] Hz must lie inside (0, fs/2) Hz");
    }
    const double lo = carrier_hz_ - bw / 2.0, hi = carrier_hz_ + bw / 2.0;
    // Doppler grid: relative speeds up to doppler_max_hz at the carrier, doppler_step_hz apart (one code's
    // coherent correlation loses < 1 dB when the step is below ~0.5 / code duration).
    const double dmax = params.get_float("doppler_max_hz"), dstep = params.get_float("doppler_step_hz");
    const int nd = dmax > 0.0 ? static_cast<int>(std::floor(dmax / dstep + 1e-9)) : 0;
    dopplers_.clear();
    for (int i = -nd; i <= nd; ++i) dopplers_.push_back(i * dstep);
    nd_ = dopplers_.size();
    d0_ = static_cast<std::size_t>(nd);

    sos_ = dsp::butter_bandpass(order, lo, hi, fs_);
    // Anti-alias low-pass after mixing: pass the band half-width, stop before the first alias.
    const double fs_d = fs_ / static_cast<double>(D_);
    const double pass = bw / 2.0;
    const double trans = std::max(100.0, std::min(fs_d - pass, fs_ / 2.0) - pass);
    std::size_t taps = static_cast<std::size_t>(std::ceil(5.5 * fs_ / trans)) | 1u;  // Blackman: ~5.5/Δf
    taps = std::clamp<std::size_t>(taps, 15, 1023);
    lp_taps_ = dsp::fir_lowpass(taps, std::min(pass + trans / 2.0, 0.49 * fs_), fs_, {dsp::FirWindow::blackman});

    // Templates through the same chain.
    templates_.clear();
    M_ = 0;
    std::size_t full_len = 0;
    std::vector<std::vector<cd>> base_t;
    // One-off, configure-time transforms of ~16k points: planned with FFTW_ESTIMATE here rather than
    // through ctx.fft, whose plans are meant for the streaming path (and may be slow reference
    // implementations in tests).
    FftwPlanner hilbert_fft({}, /*measure=*/false);
    ncodes_ = specs_.size();
    // The full length every template is padded to: the longest (slowest) Doppler version.
    std::size_t max_len = 0;
    for (const dsp::SignalSpec& spec : specs_) {
      try {
        max_len = std::max(max_len, dsp::signal_length(spec, fs_));
      } catch (const std::exception& e) {
        throw std::runtime_error(std::string("goldcode: cannot build code ") + std::to_string(spec.index) + ": " + e.what());
      }
    }
    const double alpha_min = dopplers_.empty() ? 1.0 : 1.0 + dopplers_.front() / carrier_hz_;
    max_len = static_cast<std::size_t>(std::ceil(static_cast<double>(max_len) / alpha_min)) + 1;
    for (std::size_t idx = 0; idx < ncodes_ * nd_; ++idx) {
      const dsp::SignalSpec& spec = specs_[idx / nd_];
      const double alpha = 1.0 + dopplers_[idx % nd_] / carrier_hz_;
      std::vector<float> s;
      try {
        s = render_scaled(spec, fs_, alpha);
      } catch (const std::exception& e) {
        throw std::runtime_error(std::string("goldcode: cannot build code ") + std::to_string(spec.index) + ": " + e.what());
      }
      s.resize(max_len, 0.0f);
      code_len_ = max_len;
      const std::size_t tail = taps + 8 * static_cast<std::size_t>(order) * 4;
      s.resize(s.size() + tail, 0.0f);
      full_len = s.size();
      CodeTemplate t;
      // Full-rate band-passed template, in-phase and quadrature (c·cos → c·sin is the same code on sin).
      dsp::SosFilter f1(sos_);
      t.full_i.resize(s.size());
      f1.process(s.data(), t.full_i.data(), s.size());
      t.full_q = hilbert(t.full_i, hilbert_fft);
      for (float v : t.full_i) t.full_energy += static_cast<double>(v) * v;
      // Baseband: mix the band-passed template, low-pass, decimate from frame 0.
      dsp::FirDecimator di(lp_taps_, D_), dq(lp_taps_, D_);
      std::vector<float> mi(s.size()), mq(s.size());
      for (std::size_t n = 0; n < s.size(); ++n) {
        const double ph = 2.0 * kPi * std::fmod(carrier_hz_ * static_cast<double>(n) / fs_, 1.0);
        mi[n] = static_cast<float>(t.full_i[n] * std::cos(ph));
        mq[n] = static_cast<float>(-t.full_i[n] * std::sin(ph));
      }
      std::vector<float> oi(s.size() / D_ + 2), oq(s.size() / D_ + 2);
      const std::size_t k = di.process(mi.data(), mi.size(), oi.data());
      dq.process(mq.data(), mq.size(), oq.data());
      std::vector<cd> bt(k);
      for (std::size_t i = 0; i < k; ++i) bt[i] = cd(oi[i], oq[i]);
      M_ = std::max(M_, k);
      base_t.push_back(std::move(bt));
      templates_.push_back(std::move(t));
    }
    full_len_ = full_len;
    nfft_ = std::bit_ceil(2 * M_);
    hop_ = nfft_ - M_ + 1;
    auto fft = ctx.fft.plan_real(nfft_);
    fft_ = std::move(fft);
    std::vector<float> buf(nfft_);
    for (std::size_t u = 0; u < templates_.size(); ++u) {  // every (code, Doppler) template
      std::vector<cd>& bt = base_t[u];
      bt.resize(M_, cd(0.0, 0.0));
      cd mean(0.0, 0.0);
      for (const cd& v : bt) mean += v;
      mean /= static_cast<double>(M_);
      CodeTemplate& t = templates_[u];
      t.energy = 0.0;
      for (cd& v : bt) {
        v -= mean;
        t.energy += std::norm(v);
      }
      // Complex spectrum C of T = A + j·B from the real spectra of A and B, stored conjugated and
      // split (coarse_max multiplies X·conj(C)).
      std::vector<cf> sa(nfft_ / 2 + 1), sb(nfft_ / 2 + 1);
      std::fill(buf.begin(), buf.end(), 0.0f);
      for (std::size_t i = 0; i < M_; ++i) buf[i] = static_cast<float>(bt[i].real());
      fft_->forward(buf.data(), sa.data());
      std::fill(buf.begin(), buf.end(), 0.0f);
      for (std::size_t i = 0; i < M_; ++i) buf[i] = static_cast<float>(bt[i].imag());
      fft_->forward(buf.data(), sb.data());
      t.cc_re.assign(nfft_, 0.0f);
      t.cc_im.assign(nfft_, 0.0f);
      for (std::size_t k = 0; k <= nfft_ / 2; ++k) {
        const cf a = sa[k], b = sb[k];
        t.cc_re[k] = a.real() - b.imag();
        t.cc_im[k] = -(a.imag() + b.real());
        if (k > 0 && k < nfft_ / 2) {
          t.cc_re[nfft_ - k] = a.real() + b.imag();
          t.cc_im[nfft_ - k] = -(b.real() - a.imag());
        }
      }
    }
    cfft_ = ctx.fft.plan_complex(nfft_);

    // Own-emission cancellation (dsp::EmissionCanceller): the code this device emits itself, when no
    // other source of the scene emits the same chips, is found in the raw audio, fitted with its
    // speaker-to-microphone response (cancel_pre_s before its start, cancel_post_s after: transducer
    // responses and the earliest echoes) and subtracted before every other code is searched; its
    // arrivals are reported from the fits.
    own_ = -1;
    if (params.get_bool("cancel_own") && ctx.geometry != nullptr) {
      for (std::size_t u = 0; u < ncodes_ && own_ < 0; ++u) {
        const std::vector<std::uint8_t> cu = dsp::gold_chips(specs_[u]);
        auto same = [&](const SignalSpec& sig) {
          return sig.type == "gold" && sig.carrier_hz == specs_[u].carrier_hz &&
                 sig.chip_samples == specs_[u].chip_samples && dsp::gold_chips(sig) == cu;
        };
        const bool mine = std::any_of(ctx.geometry->emits.begin(), ctx.geometry->emits.end(), same);
        if (!mine) continue;
        bool shared = false;
        for (const SceneSignal& e : ctx.geometry->scene_emits)
          if (e.id != ctx.device && same(e.signal)) shared = true;
        if (!shared) own_ = static_cast<int>(u);
      }
    }
    if (own_ >= 0) {
      dsp::EmissionCanceller::Options co;
      co.channels = channels_;
      co.taps_before = static_cast<std::size_t>(std::llround(params.get_float("cancel_pre_s") * fs_));
      co.taps_after = static_cast<std::size_t>(std::llround(params.get_float("cancel_post_s") * fs_));
      dsp::SignalSpec own = specs_[static_cast<std::size_t>(own_)];
      own.amplitude = 1.0;
      try {
        canceller_.configure(dsp::render_signal(own, fs_), ctx.fft, co);
      } catch (const std::invalid_argument& e) {
        throw std::runtime_error(std::string("goldcode: own-emission canceller: ") + e.what());
      }
      ctx.log.info("goldcode: code " + std::to_string(own_) +
                   " is this device's own emission: cancelled, the others searched in what is left");
    }
    canc_started_.assign(channels_, 0);
    canc_seen_.assign(channels_, 0);
    // Round gate: the protocol makes every user emit once per round, a known time after the radio
    // start; another user's code can only arrive within [own emission - before, own emission + after].
    {
      const std::vector<double>& w = params.get_floats("round_window_s");
      if (!w.empty() && w.size() != 2)
        throw std::runtime_error("goldcode: round_window_s must be empty (off) or [before_s, after_s], got " +
                                 std::to_string(w.size()) + " values");
      gate_ = w.size() == 2;
      if (gate_ && !(w[0] + w[1] > 0.0))
        throw std::runtime_error("goldcode: round_window_s [before_s, after_s] must span a positive time");
      if (gate_ && own_ < 0)
        throw std::runtime_error("goldcode: round_window_s needs this device's own emission (cancel_own: true and a "
                                 "scene in which the device emits one of the codes) to place the rounds");
      gate_before_ = gate_ ? w[0] * fs_ : 0.0;
      gate_after_ = gate_ ? w[1] * fs_ : 0.0;
    }
    refine_doppler_ = static_cast<std::size_t>(params.get_int("refine_doppler_steps"));
    select_amplitude_ = params.get_string("select") == "amplitude";

    // Two-path first-arrival model (first_path).
    mp_max_ = static_cast<std::size_t>(std::llround(params.get_float("multipath_max_s") * fs_));
    mp_min_ = std::max<std::size_t>(1, static_cast<std::size_t>(std::llround(params.get_float("multipath_min_s") * fs_)));
    if (mp_max_ > 0 && mp_max_ < mp_min_)
      throw std::runtime_error("goldcode: multipath_max_s must be 0 (off) or >= multipath_min_s");
    mp_gain_ = params.get_float("multipath_gain");
    gram_.assign(mp_max_ > 0 ? templates_.size() * 4 * (mp_max_ + 1) : 0, 0.0);
    gram_done_.assign(templates_.size(), 0);
    mp_res_.assign(mp_max_ > 0 ? full_len_ + 2 * mp_max_ + 8 : 0, 0.0f);
    mp_zi_.assign(mp_max_ + mp_max_ / 2 + 8, 0.0);
    mp_zq_.assign(mp_max_ + mp_max_ / 2 + 8, 0.0);

    // Working memory.
    refine_half_ = static_cast<std::int64_t>(D_ / 2 + 3);
    sep_ = params.get_float("min_separation_s") * fs_;
    const std::size_t ring_need = static_cast<std::size_t>(sep_) + 2 * mp_max_ + (2 * nfft_ + M_) * D_ + max_block_ + full_len_ + 4 * static_cast<std::size_t>(refine_half_);
    ring_size_ = std::bit_ceil(ring_need);
    ring_mask_ = ring_size_ - 1;
    chans_.assign(channels_, Channel{});
    for (Channel& ch : chans_) {
      ch.bpf = dsp::SosFilter(sos_);
      ch.dec = IqDecimator(lp_taps_, D_);
      ch.ring.assign(ring_size_, 0.0f);
      ch.xi.assign(nfft_, 0.0f);
      ch.xq.assign(nfft_, 0.0f);
      ch.cand.assign(ncodes_, Candidate{});
      ch.last_final.assign(ncodes_, INT64_MIN / 2);
      ch.last_rho.assign(ncodes_, -1.0);
      ch.fin_frame.assign(ncodes_, -1e300);
      ch.fin_ci.assign(ncodes_, 0.0);
      ch.fin_cq.assign(ncodes_, 0.0);
      ch.fin_dop.assign(ncodes_, d0_);
      ch.pend.assign(ncodes_, AudioDetection{});
      ch.pend_dop.assign(ncodes_, d0_);
      ch.has_pend.assign(ncodes_, 0);
    }
    bp_.assign(max_block_, 0.0f);
    allow_.assign(hop_, 1);
    r2f_.assign(hop_, 0.0f);
    mi_.assign(max_block_, 0.0f);
    mq_.assign(max_block_, 0.0f);
    di_.assign(max_block_ / D_ + 2, 0.0f);
    dq_.assign(max_block_ / D_ + 2, 0.0f);
    spec_xi_.assign(nfft_ / 2 + 1, cf{});
    spec_xq_.assign(nfft_ / 2 + 1, cf{});
    spec_xr_.assign(nfft_, 0.0f);
    spec_xm_.assign(nfft_, 0.0f);
    dopf_.assign(hop_, 0.0f);
    rho_.assign(hop_ * ncodes_, 0.0);
    dop_.assign(hop_ * ncodes_, 0);
    win_w_.assign(hop_, 0.0);
    noise_.assign(ncodes_, 0.0);
    members_.reserve(2 * ncodes_ + 1);  // u + per other code: last detection and open candidate
    // Members lie within one template length of the peak on either side (evaluate_peak).
    resid_.assign(3 * full_len_ + 4 * static_cast<std::size_t>(refine_half_) + 8, 0.0f);
    lag_.assign(2 * static_cast<std::size_t>(refine_half_) + 1, Lag{});
    pre_e_.assign(nfft_ + 1, 0.0);
    pre_si_.assign(nfft_ + 1, 0.0);
    pre_sq_.assign(nfft_ + 1, 0.0);
    rot_ = std::exp(cd(0.0, -2.0 * kPi * carrier_hz_ / fs_));
    expected_frame_ = 0;
    have_expected_ = false;
    dropped_ = 0;
  }

  void process_audio(const AudioBlock& block, EventSink& out) noexcept override {
    const bool gap = block.lost_before > 0 || (have_expected_ && block.first_frame != expected_frame_);
    const std::uint32_t nch = std::min(block.channels, channels_);
    for (std::uint32_t c = 0; c < channels_; ++c) {
      if (gap && own_ >= 0 && canc_started_[c]) {
        drain_canceller(c, out);
        canc_started_[c] = 0;
      }
      Channel& ch = chans_[c];
      if (gap && ch.started) {
        flush_candidates(c, out);
        ch.started = false;
      }
    }
    if (own_ >= 0) {
      for (std::uint32_t c = 0; c < nch; ++c) {
        if (!canc_started_[c]) {
          canceller_.reset(c, block.first_frame);
          canc_started_[c] = 1;
        }
        const float* x = block.channel_data[c];
        std::size_t pos = 0;
        while (pos < block.frames) {
          pos += canceller_.push(c, x + pos, block.frames - pos);
          if (canceller_.full(c)) {
            const std::size_t n = canceller_.process(c);
            chans_[c].own_known_until = static_cast<double>(canceller_.output_start(c) + n);
            report_own(c, out);
            run_chunks(c, canceller_.output(c), n, canceller_.output_start(c), out);
            canceller_.advance(c);
          }
        }
      }
    } else {
      std::uint32_t done = 0;
      while (done < block.frames) {
        const std::uint32_t n = std::min<std::uint32_t>(block.frames - done, static_cast<std::uint32_t>(max_block_));
        for (std::uint32_t c = 0; c < nch; ++c) run(c, block.channel_data[c] + done, n, block.first_frame + done, out);
        done += n;
      }
    }
    expected_frame_ = block.first_frame + block.frames;
    have_expected_ = true;
  }

  void finish(EventSink& out) override {
    if (own_ >= 0)
      for (std::uint32_t c = 0; c < channels_; ++c)
        if (canc_started_[c]) {
          drain_canceller(c, out);
          canc_started_[c] = 0;
        }
    // Push silence through so that the last codes' correlation windows complete.
    if (have_expected_) {
      std::vector<float> zeros(max_block_, 0.0f);
      const std::size_t total = (nfft_ + M_) * D_ + full_len_;
      for (std::uint32_t c = 0; c < channels_; ++c) {
        if (!chans_[c].started) continue;
        std::uint64_t frame = chans_[c].end_frame;
        for (std::size_t done = 0; done < total; done += max_block_) {
          run(c, zeros.data(), static_cast<std::uint32_t>(max_block_), frame, out);
          frame += max_block_;
        }
      }
    }
    for (std::uint32_t c = 0; c < channels_; ++c) flush_candidates(c, out);
    if (dropped_ > 0 && log_)
      log_->warn("goldcode: " + std::to_string(dropped_) + " detections dropped (event queue full)");
  }

 private:
  // Feeds n contiguous samples starting at frame `first` to run() in pieces of at most max_block_.
  void run_chunks(std::uint32_t c, const float* x, std::size_t n, std::uint64_t first, EventSink& out) noexcept {
    for (std::size_t done = 0; done < n;) {
      const std::uint32_t k = static_cast<std::uint32_t>(std::min(n - done, max_block_));
      run(c, x + done, k, first + done, out);
      done += k;
    }
  }

  // The canceller's pending samples (end of stream or a gap): cancel, report, run, forget.
  void drain_canceller(std::uint32_t c, EventSink& out) noexcept {
    const std::size_t n = canceller_.flush(c);
    chans_[c].own_known_until = static_cast<double>(canceller_.output_start(c) + n);
    report_own(c, out);
    if (n > 0) run_chunks(c, canceller_.output(c), n, canceller_.output_start(c), out);
    canceller_.reset(c, 0);
  }

  // One detection of the own code per new canceller fit (frame = the fitted start, confidence = its
  // correlation coefficient, amplitude = its level relative to the unit template, snr_db = the energy
  // removed over the emission's support, dB).
  void report_own(std::uint32_t c, EventSink& out) noexcept {
    const std::uint64_t count = canceller_.cancelled(c);
    if (count - canc_seen_[c] > dsp::EmissionCanceller::kHistory)
      canc_seen_[c] = count - dsp::EmissionCanceller::kHistory;
    for (; canc_seen_[c] < count; ++canc_seen_[c]) {
      const dsp::EmissionCanceller::Fit& f = canceller_.recent(c, count - 1 - canc_seen_[c]);
      Channel& chn = chans_[c];
      chn.own_frames[chn.own_count++ % Channel::kOwnKept] = f.peak_lag;
      AudioDetection d;
      d.device = device_;
      d.detector = detector_;
      d.stream = stream_;
      d.channel = static_cast<std::uint16_t>(c);
      d.template_index = static_cast<std::uint16_t>(own_);
      d.frame = f.peak_lag;
      d.sample_rate_hz = fs_;
      d.snr_db = static_cast<float>(f.cancelled_db);
      d.confidence = static_cast<float>(std::clamp(f.coefficient, 0.0, 1.0));
      d.amplitude = static_cast<float>(f.amplitude);
      if (!out.emit(Event{d})) ++dropped_;
    }
  }

 private:
  void restart(Channel& ch, std::uint64_t frame) noexcept {
    ch.bpf.reset();
    ch.dec.reset();
    // Decimated sample m is frame m·D: the first output comes on the next frame ≡ 0 (mod D).
    const std::size_t to_grid = (D_ - frame % D_) % D_;
    ch.dec.set_next_output(to_grid);
    // The absolute carrier phase is irrelevant (every statistic is a magnitude); it only has to be
    // continuous from here on, which the rotator guarantees.
    ch.osc = cd(1.0, 0.0);
    std::fill(ch.xi.begin(), ch.xi.end(), 0.0f);
    std::fill(ch.xq.begin(), ch.xq.end(), 0.0f);
    ch.fill = 0;
    ch.base = static_cast<std::int64_t>((frame + to_grid) / D_);
    ch.grid_start = ch.base;
    ch.start_frame = frame;
    for (Candidate& k : ch.cand) k = Candidate{};
    for (auto& l : ch.last_final) l = INT64_MIN / 2;
    for (auto& r : ch.last_rho) r = -1.0;
    for (auto& r : ch.fin_frame) r = -1e300;
    for (auto& h : ch.has_pend) h = 0;
    ch.end_frame = frame;
    ch.level = 0.0;
    ch.started = true;
  }

  void run(std::uint32_t c, const float* x, std::uint32_t n, std::uint64_t first_frame, EventSink& out) noexcept {
    Channel& ch = chans_[c];
    if (!ch.started) restart(ch, first_frame);
    ch.bpf.process(x, bp_.data(), n);
    {  // band-passed audio → ring (at most two pieces)
      const std::size_t at = first_frame & ring_mask_;
      const std::size_t n1 = std::min<std::size_t>(n, ring_size_ - at);
      std::memcpy(ch.ring.data() + at, bp_.data(), n1 * sizeof(float));
      std::memcpy(ch.ring.data(), bp_.data() + n1, (n - n1) * sizeof(float));
    }
    // Rotator in plain doubles (std::complex's operator* adds NaN checks), renormalised per block.
    double o_re = ch.osc.real(), o_im = ch.osc.imag();
    const double r_re = rot_.real(), r_im = rot_.imag();
    for (std::uint32_t i = 0; i < n; ++i) {
      const double y = bp_[i];
      mi_[i] = static_cast<float>(y * o_re);
      mq_[i] = static_cast<float>(y * o_im);
      const double t = o_re * r_re - o_im * r_im;
      o_im = o_re * r_im + o_im * r_re;
      o_re = t;
    }
    const double mag = std::sqrt(o_re * o_re + o_im * o_im);
    ch.osc = cd(o_re / mag, o_im / mag);
    ch.end_frame = first_frame + n;
    const std::size_t k = ch.dec.process(mi_.data(), mq_.data(), n, di_.data(), dq_.data());
    for (std::size_t i = 0; i < k; ++i) {
      ch.xi[ch.fill] = di_[i];
      ch.xq[ch.fill] = dq_[i];
      if (++ch.fill == nfft_) hop(c, out);
    }
  }

  // One overlap-save hop: correlation lags base .. base+hop−1 for every code.
  void hop(std::uint32_t c, EventSink& out) noexcept {
    Channel& ch = chans_[c];
    // Round gate: the lags another user's code can start at (all of them without the gate).
    std::size_t n_allowed = hop_;
    if (gate_) {
      n_allowed = 0;
      const std::size_t kept = std::min(ch.own_count, Channel::kOwnKept);
      for (std::size_t d = 0; d < hop_; ++d) {
        const double f = static_cast<double>(ch.base + static_cast<std::int64_t>(d)) * static_cast<double>(D_);
        // An own emission that could still open a window here may not be found yet: search.
        bool ok = f + gate_before_ >= ch.own_known_until;
        for (std::size_t i = 0; i < kept && !ok; ++i)
          ok = f >= ch.own_frames[i] - gate_before_ - static_cast<double>(D_) &&
               f <= ch.own_frames[i] + gate_after_ + static_cast<double>(D_);
        allow_[d] = ok ? 1 : 0;
        n_allowed += ok ? 1 : 0;
      }
    }
    if (n_allowed > 0) {
      fft_->forward(ch.xi.data(), spec_xi_.data());
      fft_->forward(ch.xq.data(), spec_xq_.data());
      // X = DFT(xi + j·xq), split: X[k] = XI[k] + j·XQ[k], X[n−k] = conj(XI[k]) + j·conj(XQ[k]).
      const std::size_t n = nfft_;
      for (std::size_t k = 0; k <= n / 2; ++k) {
        const cf a = spec_xi_[k], b = spec_xq_[k];
        spec_xr_[k] = a.real() - b.imag();
        spec_xm_[k] = a.imag() + b.real();
        if (k > 0 && k < n / 2) {
          spec_xr_[n - k] = a.real() + b.imag();
          spec_xm_[n - k] = b.real() - a.imag();
        }
      }
    }
    // Exact window sums from prefix sums.
    pre_e_[0] = pre_si_[0] = pre_sq_[0] = 0.0;
    for (std::size_t i = 0; i < nfft_; ++i) {
      const double a = ch.xi[i], b = ch.xq[i];
      pre_e_[i + 1] = pre_e_[i] + a * a + b * b;
      pre_si_[i + 1] = pre_si_[i] + a;
      pre_sq_[i + 1] = pre_sq_[i] + b;
    }
    const double inv_n = 1.0 / static_cast<double>(nfft_);
    const double m = static_cast<double>(M_);
    // Windows far below the usual level (digital silence, filter ring-down at the end of a stream)
    // make ρ meaningless: 0/0. They must hold at least 1e-3 of the running window energy.
    const double min_e = std::max(1e-20, 1e-3 * ch.level);
    const double hop_mean_e = (pre_e_[hop_ + M_ - 1] - pre_e_[0]) / static_cast<double>(hop_ + M_ - 1) * m;
    ch.level = ch.level == 0.0 ? hop_mean_e : 0.8 * ch.level + 0.2 * hop_mean_e;
    for (std::size_t d = 0; d < hop_; ++d) {
      const double si = pre_si_[d + M_] - pre_si_[d], sq = pre_sq_[d + M_] - pre_sq_[d];
      const double e = pre_e_[d + M_] - pre_e_[d] - (si * si + sq * sq) / m;
      win_w_[d] = e > min_e && (!gate_ || allow_[d]) ? inv_n * inv_n / e : 0.0;
    }
    for (std::size_t u = 0; u < ncodes_; ++u) {
      double* rho = &rho_[u * hop_];
      std::uint16_t* dop = &dop_[u * hop_];
      if (static_cast<int>(u) == own_ || n_allowed == 0) {  // own: reported from the canceller's fits
        std::fill(rho, rho + hop_, 0.0);
        noise_[u] = 1e-12;
        continue;
      }
      // ρ per lag: the best of the code's Doppler versions. The window energy does not depend on the
      // version: ρ² = |z|² / energy per version, maximised over the versions, times 1/(e·n²) once per
      // lag (squares compared, one square root per lag).
      coarse_max(u, hop_);
      for (std::size_t d = 0; d < hop_; ++d) {
        r2f_[d] *= static_cast<float>(win_w_[d]);
        dop[d] = win_w_[d] > 0.0 ? static_cast<std::uint16_t>(dopf_[d]) : static_cast<std::uint16_t>(d0_);
      }
      double sum_r2 = 0.0;
      for (std::size_t d = 0; d < hop_; ++d) {
        rho[d] = std::min(std::sqrt(static_cast<double>(r2f_[d])), 1.0);
        sum_r2 += rho[d] * rho[d];
      }
      // Mean ρ² over the lags searched (the gate's, or all of them).
      noise_[u] = std::max(sum_r2 / static_cast<double>(n_allowed), 1e-12);
    }
    // Lags in time order, all codes at each lag: when one code's candidate is final, every other
    // code's peaks up to that lag are known (needed by the joint refinement).
    for (std::size_t d = 0; d < hop_; ++d) {
      const std::int64_t lag = ch.base + static_cast<std::int64_t>(d);
      for (std::size_t u = 0; u < ncodes_; ++u) {
        if (static_cast<int>(u) == own_) continue;
        const double* rho = &rho_[u * hop_];
        step_lag(c, u, lag, rho[d], d > 0 ? rho[d - 1] : ch.last_rho[u], noise_[u], dop_[u * hop_ + d], out);
      }
    }
    for (std::size_t u = 0; u < ncodes_; ++u) ch.last_rho[u] = rho_[u * hop_ + hop_ - 1];
    std::memmove(ch.xi.data(), ch.xi.data() + hop_, (nfft_ - hop_) * sizeof(float));
    std::memmove(ch.xq.data(), ch.xq.data() + hop_, (nfft_ - hop_) * sizeof(float));
    ch.fill = nfft_ - hop_;
    ch.base += static_cast<std::int64_t>(hop_);
  }

  // The Doppler search of code u over the first `lags` lags of the hop: r2f_[d] = max over the code's
  // Doppler versions f of |z_f(d)|² / energy_f, dopf_[d] = that f. z_f = IDFT(X · conj(C_f)), X the
  // complex spectrum of the window (spec_xr_/spec_xi2_, split), C_f the version's complex template
  // spectrum (stored conjugated and split): one complex multiply per bin and one complex inverse FFT
  // per version (kernels in locus/dsp/simd.hpp).
  void coarse_max(std::size_t u, std::size_t lags) noexcept {
    std::fill(r2f_.begin(), r2f_.begin() + static_cast<std::ptrdiff_t>(lags), 0.0f);
    std::fill(dopf_.begin(), dopf_.begin() + static_cast<std::ptrdiff_t>(lags), static_cast<float>(d0_));
    const float* xr = spec_xr_.data();
    const float* xm = spec_xm_.data();
    float* r2 = r2f_.data();
    float* df = dopf_.data();
    for (std::size_t f = 0; f < nd_; ++f) {
      const CodeTemplate& t = tpl(u, f);
      simd::cmul_split(xr, xm, t.cc_re.data(), t.cc_im.data(), reinterpret_cast<float*>(cfft_->input()), nfft_);
      cfft_->inverse();
      const float inv_t = t.energy > 1e-30 ? static_cast<float>(1.0 / t.energy) : 0.0f;
      simd::max_norm(reinterpret_cast<const float*>(cfft_->output()), inv_t, static_cast<float>(f), r2, df, lags);
    }
  }

  void step_lag(std::uint32_t c, std::size_t u, std::int64_t lag, double rho, double rho_prev, double noise,
                std::uint16_t dop, EventSink& out) noexcept {
    Channel& ch = chans_[c];
    Candidate& k = ch.cand[u];
    const std::int64_t len = static_cast<std::int64_t>(M_);
    if (k.in_run && !k.cur.have_next && lag == k.cur.lag + 1) {
      k.cur.rho_next = rho;
      k.cur.have_next = true;
    }
    for (int i = 0; i < k.npeaks; ++i)
      if (!k.peaks[i].have_next && lag == k.peaks[i].lag + 1) {
        k.peaks[i].rho_next = rho;
        k.peaks[i].have_next = true;
      }
    // A waiting detection is final once no candidate within the separation can still be open.
    if (ch.has_pend[u] && static_cast<double>(lag) > (ch.pend[u].frame + sep_) / static_cast<double>(D_) +
                                                         static_cast<double>(len + 5 + (2 * refine_half_) / static_cast<std::int64_t>(D_)))
      emit_pending(c, u, out);
    // Final one code length after the first peak, plus the lags the full-rate refinement reaches.
    if (k.open && lag > k.first_lag + len + 3 + (2 * refine_half_) / static_cast<std::int64_t>(D_)) finalize(c, u, out);
    if (lag < ch.grid_start) return;  // window reaches back before the data since the last restart
    // ρ²/noise ≥ 10^(min_snr_db/10), without a logarithm per lag and code.
    // Without the separation rule, the half code after a detection belongs to it; with it, a stronger
    // peak there replaces a weaker detection (offer()).
    if (rho >= min_rho_coarse_ && rho * rho >= min_snr_lin_ * noise && (sep_ > 0.0 || lag > ch.last_final[u] + len / 2)) {
      if (!k.open) {
        k.open = true;
        k.first_lag = lag;
        k.npeaks = 0;
        k.rho = 0.0;
      }
      if (!k.in_run || rho > k.cur.rho) k.cur = Peak{lag, rho, rho_prev, -1.0, false, dop};
      k.in_run = true;
      k.last_above = lag;
      if (rho > k.rho) {
        k.rho = rho;
        k.lag = lag;
        k.noise = noise;
        k.dop = dop;
      }
    } else if (k.in_run && lag > k.last_above + 2) {
      push_peak(k);
    }
  }

  static void push_peak(Candidate& k) noexcept {
    k.in_run = false;
    if (k.npeaks < Candidate::kMaxPeaks) {
      k.peaks[k.npeaks++] = k.cur;
      return;
    }
    int weakest = 0;
    for (int i = 1; i < k.npeaks; ++i)
      if (k.peaks[i].rho < k.peaks[weakest].rho) weakest = i;
    if (k.cur.rho > k.peaks[weakest].rho) k.peaks[weakest] = k.cur;
  }

  void flush_candidates(std::uint32_t c, EventSink& out) noexcept {
    for (std::size_t u = 0; u < ncodes_; ++u)
      if (chans_[c].cand[u].open) finalize(c, u, out);
    for (std::size_t u = 0; u < ncodes_; ++u) emit_pending(c, u, out);
  }

  // Kernels of the refinement: locus/dsp/simd.hpp (8 float lanes per accumulator, the partial sums
  // added in double: relative error ~1e-6, plenty for a peak search and least-squares amplitudes).
  static double energy(const float* y, std::size_t n) noexcept { return simd::energy(y, n); }
  static void dot2(const float* y, const float* a, const float* b, std::size_t n, double& ra, double& rb) noexcept {
    simd::dot2(y, a, b, n, ra, rb);
  }
  static void sub2(float* y, const float* a, const float* b, float ci, float cq, std::size_t n) noexcept {
    simd::sub2(y, a, b, ci, cq, n);
  }

  // Re-estimates one member's arrival (±half frames around its estimate) and in-phase/quadrature
  // amplitudes on the signal minus every other member's current reconstruction.
  // Σ x² of the band-passed audio over frames [first, first + n) (ring, at most two pieces).
  double ring_energy(const Channel& ch, std::int64_t first, std::size_t n) const noexcept {
    const std::size_t at = static_cast<std::uint64_t>(first) & ring_mask_;
    const std::size_t n1 = std::min(n, ring_size_ - at);
    return energy(ch.ring.data() + at, n1) + energy(ch.ring.data(), n - n1);
  }

  // resid_ += sign · (ci·g_i + cq·g_q) at the member's subtracted position `at`.
  void add_recon(const Member& mb, float sign) noexcept {
    const CodeTemplate& t = tpl(mb.code, mb.dop);
    sub2(resid_.data() + (mb.at - res_lo_), t.full_i.data(), t.full_q.data(), -sign * static_cast<float>(mb.ci),
         -sign * static_cast<float>(mb.cq), full_len_);
  }

  void refine_member(const Channel& ch, Member& mb, std::int64_t half) noexcept {
    const std::int64_t centre = static_cast<std::int64_t>(std::llround(mb.frame));
    const std::int64_t lo = centre - half;
    float* const resid = resid_.data() + (lo - res_lo_);
    if (incremental_) {
      // resid_ holds the signal minus every member's current reconstruction (evaluate_peak): put
      // this member's own back, search, subtract the new one (two passes instead of one per other
      // member: cheaper from 3 members on).
      if (mb.ci != 0.0 || mb.cq != 0.0) add_recon(mb, +1.0f);
    } else {
      // Fresh: the audio over the search reach minus the other members' reconstructions.
      const std::size_t span = full_len_ + 2 * static_cast<std::size_t>(half) + 1;
      const std::size_t at = static_cast<std::uint64_t>(lo) & ring_mask_;  // at most two pieces
      const std::size_t n1 = std::min(span, ring_size_ - at);
      std::memcpy(resid, ch.ring.data() + at, n1 * sizeof(float));
      std::memcpy(resid + n1, ch.ring.data(), (span - n1) * sizeof(float));
      for (const Member& o : members_) {
        if (&o == &mb || (o.ci == 0.0 && o.cq == 0.0)) continue;
        const CodeTemplate& to = tpl(o.code, o.dop);
        // resid[i] covers frame lo+i; o's template sample j sits at frame o.at+j.
        const std::int64_t j0 = std::max<std::int64_t>(0, lo - o.at);
        const std::int64_t j1 = std::min<std::int64_t>(static_cast<std::int64_t>(full_len_), lo + static_cast<std::int64_t>(span) - o.at);
        if (j1 > j0)
          sub2(resid + (o.at + j0 - lo), to.full_i.data() + j0, to.full_q.data() + j0, static_cast<float>(o.ci),
               static_cast<float>(o.cq), static_cast<std::size_t>(j1 - j0));
      }
    }
    // Per Doppler version near the member's (the coarse grid's neighbours on a first refinement, its
    // own afterwards): hill climb on the matched-filter envelope from the centre (the envelope's main
    // lobe is ~fs/band_width wide, wider than the ±half window): the local maximum nearest the
    // estimate, in 3..half+2 correlations instead of 2·half+1. The version with the largest envelope wins.
    const std::int64_t last = 2 * half;
    const std::size_t reach = half > 1 ? refine_doppler_ : 0;
    const std::size_t f_lo = mb.dop >= reach ? mb.dop - reach : 0;
    const std::size_t f_hi = std::min(nd_ - 1, mb.dop + reach);
    double best_all = -1.0, bi = 0.0, bq = 0.0, off_best = 0.0;
    std::int64_t l_best = half;
    std::size_t f_best = mb.dop;
    for (std::size_t f = f_lo; f <= f_hi; ++f) {
      const CodeTemplate& t = tpl(mb.code, f);
      auto eval = [&](std::int64_t l) noexcept {
        Lag& g = lag_[static_cast<std::size_t>(l)];
        if (!g.done) {
          dot2(resid + l, t.full_i.data(), t.full_q.data(), full_len_, g.ai, g.aq);
          g.e = std::sqrt(g.ai * g.ai + g.aq * g.aq);
          g.done = true;
        }
        return g.e;
      };
      for (std::int64_t l = 0; l <= last; ++l) lag_[static_cast<std::size_t>(l)].done = false;
      std::int64_t best_l = half;
      double best = eval(best_l);
      for (;;) {
        const double el = best_l > 0 ? eval(best_l - 1) : -1.0;
        const double er = best_l < last ? eval(best_l + 1) : -1.0;
        if (el > best && el >= er) {
          --best_l;
          best = el;
        } else if (er > best) {
          ++best_l;
          best = er;
        } else {
          break;
        }
      }
      if (!(best > best_all)) continue;
      const double e_bp = best_l > 0 ? eval(best_l - 1) : -1.0;
      const double e_bn = best_l < last ? eval(best_l + 1) : -1.0;
      double off = 0.0;
      if (e_bp >= 0.0 && e_bn >= 0.0) {
        const double den = e_bp - 2.0 * best + e_bn;
        if (den < 0.0) off = std::clamp(0.5 * (e_bp - e_bn) / den, -0.5, 0.5);
      }
      best_all = best;
      bi = lag_[static_cast<std::size_t>(best_l)].ai;
      bq = lag_[static_cast<std::size_t>(best_l)].aq;
      off_best = off;
      l_best = best_l;
      f_best = f;
    }
    const CodeTemplate& t = tpl(mb.code, f_best);
    mb.dop = f_best;
    mb.frame = static_cast<double>(lo + l_best) + off_best;
    const double e_res = energy(resid + l_best, full_len_);
    mb.rho_fine = e_res > 0.0 && t.full_energy > 0.0 ? best_all / std::sqrt(e_res * t.full_energy) : 0.0;
    // A residual ≥ 60 dB below the audio is the others' reconstruction rounding, not a signal: its
    // Pearson coefficient is noise of float arithmetic (noise-free input).
    if (mb.rho_fine >= min_rho_ && e_res < 1e-6 * ring_energy(ch, lo + l_best, full_len_)) mb.rho_fine = 0.0;
    mb.ci = t.full_energy > 0.0 ? bi / t.full_energy : 0.0;
    mb.cq = t.full_energy > 0.0 ? bq / t.full_energy : 0.0;
    mb.at = static_cast<std::int64_t>(std::llround(mb.frame));
    if (incremental_ && (mb.ci != 0.0 || mb.cq != 0.0)) add_recon(mb, -1.0f);
  }

  // Joint refinement of code u's peak `k`: arrival frame, amplitude and the refined Pearson
  // coefficient (1 when the audio around it is not available any more: the coarse value stands).
  void evaluate_peak(Channel& ch, std::size_t u, const Peak& k, double& frame, double& amp, double& rho_fine,
                     double& ci, double& cq) noexcept {
    // Coarse: parabola through ρ at lag−1, lag, lag+1 (decimated).
    double off = 0.0;
    if (k.rho_prev >= 0.0 && k.have_next) {
      const double den = k.rho_prev - 2.0 * k.rho + k.rho_next;
      if (den < 0.0) off = std::clamp(0.5 * (k.rho_prev - k.rho_next) / den, -0.5, 0.5);
    }
    const double coarse = (static_cast<double>(k.lag) + off) * static_cast<double>(D_);
    // Fine: joint refinement of this code and every other code whose emission overlaps it
    // (successive interference cancellation over the full-rate analytic matched filter).
    frame = coarse;
    amp = 0.0;
    rho_fine = k.rho;
    ci = cq = 0.0;
    eval_dop_ = k.dop;
    members_.clear();
    members_.push_back(Member{u, coarse, 0.0, 0.0, k.rho, false});
    members_.back().dop = k.dop;
    const double overlap = static_cast<double>(full_len_);
    for (std::size_t v = 0; v < ncodes_; ++v) {
      if (v == u || static_cast<int>(v) == own_) continue;
      const Candidate& kv = ch.cand[v];
      const bool fin_near = std::abs(ch.fin_frame[v] - coarse) < overlap;
      if (fin_near) {
        members_.push_back(Member{v, ch.fin_frame[v], ch.fin_ci[v], ch.fin_cq[v], 1.0, true});
        members_.back().dop = ch.fin_dop[v];
      }
      const double open_frame = static_cast<double>(kv.lag) * static_cast<double>(D_);
      if (kv.open && std::abs(open_frame - coarse) < overlap &&
          (!fin_near || std::abs(open_frame - ch.fin_frame[v]) > overlap / 2))
      {
        members_.push_back(Member{v, open_frame, 0.0, 0.0, kv.rho, false});
        members_.back().dop = kv.dop;
      }
    }
    // Strongest first (known ones are already refined: they only get subtracted in round 0).
    std::sort(members_.begin(), members_.end(), [](const Member& a, const Member& b) { return a.rho > b.rho; });
    const std::int64_t oldest = std::max<std::int64_t>(static_cast<std::int64_t>(ch.start_frame),
                                                       static_cast<std::int64_t>(ch.end_frame) - static_cast<std::int64_t>(ring_size_));
    // Members whose audio is not (or no longer) in the ring cannot take part.
    auto available = [&](const Member& mb) {
      const std::int64_t c0 = static_cast<std::int64_t>(std::llround(mb.frame));
      return c0 - 2 * refine_half_ >= oldest &&
             c0 + 2 * refine_half_ + static_cast<std::int64_t>(full_len_) <= static_cast<std::int64_t>(ch.end_frame);
    };
    members_.erase(std::remove_if(members_.begin(), members_.end(), [&](const Member& mb) { return !available(mb); }),
                   members_.end());
    const bool self_ok = std::any_of(members_.begin(), members_.end(), [&](const Member& mb) { return mb.code == u; });
    rho_fine = k.rho;  // without the refinement the coarse coefficient is all there is
    // One residual buffer over every member's reach: a member moves by ≤ refine_half_ + 1/2 in
    // round 0 and ≤ 3/2 in round 1, inside the 2·refine_half_ margin `available` guarantees.
    std::int64_t first = INT64_MAX, end = INT64_MIN;
    for (Member& mb : members_) {
      mb.at = static_cast<std::int64_t>(std::llround(mb.frame));
      first = std::min(first, mb.at - 2 * refine_half_);
      end = std::max(end, mb.at + 2 * refine_half_ + static_cast<std::int64_t>(full_len_));
    }
    if (self_ok && end - first <= static_cast<std::int64_t>(resid_.size())) {
      res_lo_ = first;
      incremental_ = members_.size() >= 3;
      if (incremental_) {
        const std::size_t span = static_cast<std::size_t>(end - first);
        const std::size_t at = static_cast<std::uint64_t>(first) & ring_mask_;  // at most two pieces
        const std::size_t n1 = std::min(span, ring_size_ - at);
        std::memcpy(resid_.data(), ch.ring.data() + at, n1 * sizeof(float));
        std::memcpy(resid_.data() + n1, ch.ring.data(), (span - n1) * sizeof(float));
        for (const Member& mb : members_)
          if (mb.ci != 0.0 || mb.cq != 0.0) add_recon(mb, -1.0f);
      }
      const int rounds = members_.size() > 1 ? 2 : 1;
      for (int round = 0; round < rounds; ++round) {
        for (Member& mb : members_) {
          if (mb.known && round == 0) continue;
          const std::int64_t half = mb.ci == 0.0 && mb.cq == 0.0 ? refine_half_ : 1;
          refine_member(ch, mb, half);
        }
      }
      for (const Member& mb : members_)
        if (mb.code == u) {
          frame = mb.frame;
          amp = std::hypot(mb.ci, mb.cq);
          rho_fine = mb.rho_fine;
          ci = mb.ci;
          cq = mb.cq;
          eval_dop_ = mb.dop;
        }
    }
  }

  // Σ_m x[m]·y[m − d] over the template support, d = 0..mp_max_: the template's auto/cross-correlations
  // the two-path model needs (computed on first use per code and Doppler version; buffers from configure).
  const double* path_gram(std::size_t code, std::size_t f) noexcept {
    const std::size_t idx = code * nd_ + f;
    double* g = gram_.data() + idx * 4 * (mp_max_ + 1);
    if (!gram_done_[idx]) {
      const CodeTemplate& t = tpl(code, f);
      for (std::size_t d = 0; d <= mp_max_; ++d) {
        const std::size_t n = full_len_ - d;
        double ii, iq, qi, qq;
        dot2(t.full_i.data() + d, t.full_i.data(), t.full_q.data(), n, ii, iq);
        dot2(t.full_q.data() + d, t.full_i.data(), t.full_q.data(), n, qi, qq);
        g[4 * d + 0] = ii;
        g[4 * d + 1] = iq;
        g[4 * d + 2] = qi;
        g[4 * d + 3] = qq;
      }
      gram_done_[idx] = 1;
    }
    return g;
  }

  // First path of an arrival whose matched-filter envelope peaks at `frame` (code u, Doppler bin f):
  // a direct path and a reflection closely behind it (the floor, ~10-60 samples at 19 kHz over 3-15 m)
  // merge into one envelope peak that lies between them. Model: the residual (audio minus the other
  // codes' last reconstructions) around the arrival as a1·T(n − τ1) + a2·T(n − τ1 − δ), T the analytic
  // template (in-phase and quadrature, real least squares), τ1 within [frame − mp_max_/2, frame + 2],
  // δ in [mp_min_, mp_max_]; the pair explaining most energy wins. Its earlier path is the arrival when
  // the pair explains > (1 + multipath_gain) × the best single path and the earlier path holds at
  // least half the later one's power; else the single path. Parabolic interpolation over τ1.
  double first_path(const Channel& ch, std::size_t u, std::size_t f, double frame) noexcept {
    if (mp_max_ == 0) return frame;
    const std::int64_t at = static_cast<std::int64_t>(std::llround(frame));
    const std::int64_t l0 = at - static_cast<std::int64_t>(mp_max_ / 2), l1 = at + 2;
    const std::int64_t span_lags = l1 - l0 + 1 + static_cast<std::int64_t>(mp_max_);
    const std::int64_t oldest = std::max<std::int64_t>(static_cast<std::int64_t>(ch.start_frame),
                                                       static_cast<std::int64_t>(ch.end_frame) - static_cast<std::int64_t>(ring_size_));
    const std::size_t span = static_cast<std::size_t>(span_lags) + full_len_;
    if (l0 < oldest || l0 + static_cast<std::int64_t>(span) > static_cast<std::int64_t>(ch.end_frame) ||
        span > mp_res_.size())
      return frame;
    float* r = mp_res_.data();
    {
      const std::size_t a = static_cast<std::uint64_t>(l0) & ring_mask_;
      const std::size_t n1 = std::min(span, ring_size_ - a);
      std::memcpy(r, ch.ring.data() + a, n1 * sizeof(float));
      std::memcpy(r + n1, ch.ring.data(), (span - n1) * sizeof(float));
    }
    for (std::size_t v = 0; v < ncodes_; ++v) {  // the other codes' last detections, where they overlap
      if (v == u || static_cast<int>(v) == own_ || (ch.fin_ci[v] == 0.0 && ch.fin_cq[v] == 0.0)) continue;
      const std::int64_t ov = static_cast<std::int64_t>(std::llround(ch.fin_frame[v]));
      const CodeTemplate& to = tpl(v, ch.fin_dop[v]);
      const std::int64_t j0 = std::max<std::int64_t>(0, l0 - ov);
      const std::int64_t j1 = std::min<std::int64_t>(static_cast<std::int64_t>(full_len_), l0 + static_cast<std::int64_t>(span) - ov);
      if (j1 > j0)
        sub2(r + (ov + j0 - l0), to.full_i.data() + j0, to.full_q.data() + j0, static_cast<float>(ch.fin_ci[v]),
             static_cast<float>(ch.fin_cq[v]), static_cast<std::size_t>(j1 - j0));
    }
    const CodeTemplate& t = tpl(u, f);
    for (std::int64_t j = 0; j < span_lags; ++j)
      dot2(r + j, t.full_i.data(), t.full_q.data(), full_len_, mp_zi_[static_cast<std::size_t>(j)], mp_zq_[static_cast<std::size_t>(j)]);
    const double* g = path_gram(u, f);
    const double eii = g[0], eiq = g[1], eqq = g[3];
    const std::int64_t nl = l1 - l0 + 1;
    // Single path: the best lag's explained energy (2x2 least squares, in-phase and quadrature).
    const double det1 = eii * eqq - eiq * eiq;
    if (!(det1 > 0.0)) return frame;
    double best1 = 0.0;
    for (std::int64_t j = 0; j < nl; ++j) {
      const double zi = mp_zi_[static_cast<std::size_t>(j)], zq = mp_zq_[static_cast<std::size_t>(j)];
      best1 = std::max(best1, (eqq * zi * zi - 2.0 * eiq * zi * zq + eii * zq * zq) / det1);
    }
    // Two paths: 4x4 normal equations per (τ1, δ). The Gram matrix G depends on δ only: its inverse
    // once per δ (Cholesky, positive-definiteness checked on the way), then per τ1 the amplitudes
    // c = G⁻¹b and the explained energy bᵀc (no division in the τ1 loop).
    struct Gram4 {
      double inv[4][4] = {};
      bool ok = false;
    };
    auto factor = [&](std::size_t d) noexcept {
      Gram4 f;
      const double* gd = g + 4 * d;
      const double G[4][4] = {{eii, eiq, gd[0], gd[1]}, {eiq, eqq, gd[2], gd[3]}, {gd[0], gd[2], eii, eiq}, {gd[1], gd[3], eiq, eqq}};
      double L[4][4] = {}, Li[4][4] = {};
      for (int i = 0; i < 4; ++i)
        for (int k = 0; k <= i; ++k) {
          double sum = G[i][k];
          for (int m = 0; m < k; ++m) sum -= L[i][m] * L[k][m];
          if (i == k) {
            if (!(sum > 1e-9 * eii)) return f;
            L[i][i] = std::sqrt(sum);
          } else {
            L[i][k] = sum / L[k][k];
          }
        }
      for (int k = 0; k < 4; ++k) {  // L⁻¹ (lower triangular), column by column
        Li[k][k] = 1.0 / L[k][k];
        for (int i = k + 1; i < 4; ++i) {
          double sum = 0.0;
          for (int m = k; m < i; ++m) sum -= L[i][m] * Li[m][k];
          Li[i][k] = sum / L[i][i];
        }
      }
      for (int r = 0; r < 4; ++r)  // G⁻¹ = L⁻ᵀ L⁻¹
        for (int q = 0; q < 4; ++q) {
          double sum = 0.0;
          for (int i = std::max(r, q); i < 4; ++i) sum += Li[i][r] * Li[i][q];
          f.inv[r][q] = sum;
        }
      f.ok = true;
      return f;
    };
    auto explain2 = [&](const Gram4& f, std::int64_t j, std::size_t d, double& p1, double& p2) noexcept {
      if (!f.ok) return -1.0;
      const double b[4] = {mp_zi_[static_cast<std::size_t>(j)], mp_zq_[static_cast<std::size_t>(j)],
                           mp_zi_[static_cast<std::size_t>(j) + d], mp_zq_[static_cast<std::size_t>(j) + d]};
      double c[4];
      for (int r = 0; r < 4; ++r) c[r] = f.inv[r][0] * b[0] + f.inv[r][1] * b[1] + f.inv[r][2] * b[2] + f.inv[r][3] * b[3];
      p1 = c[0] * c[0] + c[1] * c[1];
      p2 = c[2] * c[2] + c[3] * c[3];
      return b[0] * c[0] + b[1] * c[1] + b[2] * c[2] + b[3] * c[3];
    };
    double best2 = -1.0, bp1 = 0.0, bp2 = 0.0;
    std::int64_t bj = -1;
    std::size_t bd = 0;
    Gram4 fbest;
    for (std::size_t d = mp_min_; d <= mp_max_; ++d) {
      const Gram4 f = factor(d);
      if (!f.ok) continue;
      for (std::int64_t j = 0; j < nl; ++j) {
        double p1, p2;
        const double e = explain2(f, j, d, p1, p2);
        // The first maximum in (τ1, δ) order, as a τ1-major scan finds it.
        if (e > best2 || (e == best2 && bj >= 0 && (j < bj || (j == bj && d < bd)))) {
          best2 = e;
          bj = j;
          bd = d;
          bp1 = p1;
          bp2 = p2;
          fbest = f;
        }
      }
    }
    if (bj < 0 || !(best2 > (1.0 + mp_gain_) * best1) || !(bp1 >= 0.5 * bp2)) return frame;
    double off = 0.0;
    if (bj > 0 && bj + 1 < nl) {
      double q1, q2;
      const double em = explain2(fbest, bj - 1, bd, q1, q2), ep = explain2(fbest, bj + 1, bd, q1, q2);
      const double den = em - 2.0 * best2 + ep;
      if (em >= 0.0 && ep >= 0.0 && den < 0.0) off = std::clamp(0.5 * (em - ep) / den, -0.5, 0.5);
    }
    return static_cast<double>(l0 + bj) + off;
  }

  void finalize(std::uint32_t c, std::size_t u, EventSink& out) noexcept {
    Channel& ch = chans_[c];
    Candidate& k = ch.cand[u];
    if (k.in_run) push_peak(k);
    k.open = false;
    double frame = 0.0, amp = 0.0, rho_fine = -1.0, ci = 0.0, cq = 0.0;
    std::size_t dop = k.dop;
    std::int64_t lag = k.lag;
    double rho_c = k.rho;
    for (int i = 0; i < k.npeaks; ++i) {
      double f, a, r, pi, pq;
      evaluate_peak(ch, u, k.peaks[i], f, a, r, pi, pq);
      // The kept peak: the largest refined amplitude among those that pass the Pearson test (a
      // normalised coefficient favours lags where the window holds less interference, not the code).
      const bool better = select_amplitude_ ? (r >= min_rho_ && (rho_fine < min_rho_ || a > amp)) || (rho_fine < min_rho_ && r > rho_fine)
                                            : r > rho_fine;
      if (better) {
        frame = f;
        amp = a;
        rho_fine = r;
        ci = pi;
        cq = pq;
        dop = eval_dop_;
        lag = k.peaks[i].lag;
        rho_c = k.peaks[i].rho;
      }
    }
    k.npeaks = 0;
    // A peak that was only the other users' cross-correlation vanishes once they are subtracted.
    if (rho_fine < min_rho_) {
      ++rejected_;  // the last accepted detection of u stays the reference for the others
      return;
    }
    ch.last_final[u] = lag;
    ch.fin_frame[u] = frame;
    ch.fin_ci[u] = ci;
    ch.fin_cq[u] = cq;
    ch.fin_dop[u] = dop;
    AudioDetection d;
    d.device = device_;
    d.detector = detector_;
    d.stream = stream_;
    d.channel = static_cast<std::uint16_t>(c);
    d.template_index = static_cast<std::uint16_t>(u);
    d.frame = frame;  // the envelope peak until emit_pending() finds the first path
    d.sample_rate_hz = fs_;
    d.snr_db = static_cast<float>(10.0 * std::log10(rho_c * rho_c / k.noise));
    d.confidence = static_cast<float>(std::clamp(rho_fine, 0.0, 1.0));
    d.amplitude = static_cast<float>(amp);
    offer(c, u, d, dop, out);
  }

  // Non-maximum suppression per code: of the accepted peaks closer than min_separation_s, only the
  // one with the largest refined amplitude is reported (the others are the interference's peaks: the
  // other users' cross-correlation and reverberation lift the code's matched filter around an
  // emission burst). A peak waits until nothing within the separation can still replace it.
  void offer(std::uint32_t c, std::size_t u, const AudioDetection& d, std::size_t dop, EventSink& out) noexcept {
    Channel& ch = chans_[c];
    if (ch.has_pend[u] && std::abs(d.frame - ch.pend[u].frame) < sep_) {
      if (d.amplitude > ch.pend[u].amplitude) {
        ch.pend[u] = d;
        ch.pend_dop[u] = dop;
      }
      return;
    }
    if (ch.has_pend[u]) emit_pending(c, u, out);
    ch.pend[u] = d;
    ch.pend_dop[u] = dop;
    ch.has_pend[u] = 1;
  }

  void emit_pending(std::uint32_t c, std::size_t u, EventSink& out) noexcept {
    Channel& ch = chans_[c];
    if (!ch.has_pend[u]) return;
    AudioDetection d = ch.pend[u];
    d.frame = first_path(ch, u, ch.pend_dop[u], d.frame);
    ch.has_pend[u] = 0;
    if (!out.emit(Event{d})) ++dropped_;
  }

  Logger* log_ = nullptr;
  DeviceId device_;
  NameTag detector_;
  std::uint32_t stream_ = 0;
  std::uint32_t channels_ = 0;
  std::size_t max_block_ = 1024;
  double fs_ = 44100.0;
  double carrier_hz_ = 19000.0;
  double min_rho_ = 0.2;
  double min_rho_coarse_ = 0.15;
  double min_snr_db_ = 10.0;
  double min_snr_lin_ = 10.0;
  std::size_t D_ = 1;
  std::vector<dsp::SignalSpec> specs_;  // the codes, in template_index order
  std::size_t ncodes_ = 0;
  std::vector<double> dopplers_;         // Doppler grid (Hz at the carrier), ascending, 0 at d0_
  std::size_t nd_ = 1, d0_ = 0;
  std::size_t refine_doppler_ = 1;       // grid steps searched either side of the coarse Doppler
  std::vector<std::uint16_t> dop_;       // per code and lag of a hop: the best Doppler bin
  std::vector<double> win_w_;            // per lag of a hop: 1 / (window energy · nfft²), 0 = too quiet
  int own_ = -1;                         // the code this device emits itself (cancelled), -1 = none
  dsp::EmissionCanceller canceller_;
  std::vector<std::uint8_t> canc_started_;  // per channel: the canceller holds this stream's samples
  std::vector<std::uint64_t> canc_seen_;    // per channel: canceller fits already reported
  const CodeTemplate& tpl(std::size_t code, std::size_t f) const noexcept { return templates_[code * nd_ + f]; }
  std::vector<dsp::Biquad> sos_;
  std::vector<double> lp_taps_;
  std::vector<CodeTemplate> templates_;
  std::size_t code_len_ = 0, full_len_ = 0, M_ = 0, nfft_ = 0, hop_ = 0;
  std::int64_t refine_half_ = 4;
  std::size_t ring_size_ = 0, ring_mask_ = 0;
  std::unique_ptr<RealFft> fft_;
  std::vector<Channel> chans_;
  std::vector<float> bp_, mi_, mq_, di_, dq_;
  std::vector<cf> spec_xi_, spec_xq_;
  std::vector<float> spec_xr_, spec_xm_;  // the window's complex spectrum X (split)
  std::unique_ptr<ComplexFft> cfft_;      // the coarse search's inverse transform (nfft_)
  std::vector<float> dopf_;               // per lag of a hop: the best Doppler version (float)
  std::vector<std::uint8_t> allow_;  // per lag of a hop: inside a round window (round_window_s)
  std::vector<float> r2f_;           // per lag of a hop: best ρ² over the Doppler versions
  bool gate_ = false;                // round_window_s set
  double gate_before_ = 0.0, gate_after_ = 0.0;  // frames
  std::vector<double> rho_, noise_, pre_e_, pre_si_, pre_sq_;
  std::vector<Member> members_;
  std::size_t eval_dop_ = 0;
  bool select_amplitude_ = true;
  double sep_ = 0.0;  // min_separation_s in frames
  std::size_t mp_min_ = 8, mp_max_ = 100;  // two-path model: reflection delays searched (frames)
  double mp_gain_ = 0.1;
  std::vector<double> gram_;               // per (code, Doppler): 4·(mp_max_+1) template correlations
  std::vector<std::uint8_t> gram_done_;
  std::vector<float> mp_res_;
  std::vector<double> mp_zi_, mp_zq_;  // Doppler bin of the last evaluate_peak's own member
  std::vector<float> resid_;  // joint refinement residual; resid_[i] is frame res_lo_ + i
  std::int64_t res_lo_ = 0;
  bool incremental_ = false;  // resid_ kept up to date across refinements (≥ 3 members)
  struct Lag {
    double ai = 0.0, aq = 0.0, e = 0.0;
    bool done = false;
  };
  std::vector<Lag> lag_;  // refinement: matched-filter outputs per lag of the search window
  cd rot_{1.0, 0.0};
  std::uint64_t expected_frame_ = 0;
  bool have_expected_ = false;
  std::uint64_t dropped_ = 0;
  std::uint64_t rejected_ = 0;  // candidates rejected by the refined (interference-free) Pearson test
};

const ParamSchema* schema_fn() { return &schema(); }
Detector* create() { return new GoldcodeDetector(); }

}  // namespace

const ParamSchema& schema() {
  static const ParamSchema schema = {
      float_param("carrier_hz", 19000.0, 100.0, 100000.0, "Hz", "Carrier of the coded tones (Montage: 19 kHz)."),
      int_param("chip_samples", std::int64_t{40}, 1, 100000, "", "Samples per chip at the stream rate (Montage: 40)."),
      int_param("degree", std::int64_t{7}, 5, 11, "", "Gold code degree r: length 2^r - 1 (format pairs: 5,6,7,9,10,11)."),
      float_list_param("codes", std::vector<double>{0.0, 1.0, 2.0, 3.0}, 0.0, 2049.0, "",
                       "Family indices of the users' codes; template_index of a detection is the position here.", 1, 64),
      float_param("band_width_hz", 3600.0, 50.0, 40000.0, "Hz", "Width of the band-pass around the carrier (40-sample chips at 44.1 kHz: main lobe +-1.1 kHz and the first side lobes, which sharpen the arrival)."),
      int_param("filter_order", std::int64_t{4}, 1, 12, "", "Butterworth prototype order of the band-pass (2x poles)."),
      int_param("decimation", std::int64_t{0}, 0, 64, "", "Baseband decimation factor; 0 = floor(fs / (1.6 band_width_hz))."),
      float_param("min_pearson_coarse", 0.15, 0.01, 1.0, "",
                  "Pearson coefficient (baseband, all users present) that opens a candidate."),
      float_param("min_snr_db", 4.5, 0.0, 60.0, "dB", "Candidate peak rho^2 over the mean rho^2 of the code in the hop (low: the interference of an emission burst lifts the mean; min_pearson and the separation rule decide)."),
      float_param("min_pearson", 0.2, 0.01, 1.0, "",
                  "Pearson coefficient of the full-rate refinement, other users subtracted, a detection must reach."),
      bool_param("from_scene", false,
                 "Codes = the scene's gold signals in scene order (their chips, carrier and chip_samples) instead of "
                 "`codes`; template_index k is the k-th gold emitter of the scene."),
      bool_param("cancel_own", true,
                 "Cancel this device's own code (fitted with its speaker-to-mic response, dsp::EmissionCanceller) "
                 "before searching the others; its arrivals come from the fits. Needs the scene geometry."),
      float_param("cancel_pre_s", 0.0015, 0.0, 0.01, "s",
                  "Own-emission canceller: fitted response before the code's start (non-causal transducer responses)."),
      float_param("cancel_post_s", 0.008, 0.0, 0.05, "s",
                  "Own-emission canceller: fitted response after the start (transducer ringing, earliest echoes)."),
      float_param("doppler_max_hz", 150.0, 0.0, 2000.0, "Hz",
                  "Doppler search range at the carrier, +-: relative speeds up to c * doppler_max_hz / carrier (0 = none)."),
      float_param("doppler_step_hz", 5.0, 0.5, 500.0, "Hz",
                  "Doppler grid step (coherent loss < 1 dB below ~0.5 / code duration; 127 chips of 40: 4.3 Hz)."),
      float_param("multipath_max_s", 0.00227, 0.0, 0.01, "s",
                  "Two-path first-arrival model: longest reflection delay behind the direct path (0 = off: the "
                  "envelope peak is the arrival)."),
      float_param("multipath_min_s", 0.00018, 0.00002, 0.005, "s",
                  "Two-path model: shortest reflection delay (below it the two paths are not resolvable in the band)."),
      float_param("multipath_gain", 0.1, 0.0, 10.0, "",
                  "Two-path model: the pair must explain this fraction more energy than the best single path."),
      enum_param("select", std::string("amplitude"), {"amplitude", "pearson"},
                   "Among a code's peaks within one code length: the largest refined amplitude that passes "
                   "min_pearson (amplitude), or the largest refined Pearson coefficient (pearson)."),
      float_param("min_separation_s", 0.45, 0.0, 10.0, "s",
                  "Detections of one code closer than this: only the strongest is reported (keep it below the "
                  "emission period; 0 = every accepted peak)."),
      int_param("refine_doppler_steps", std::int64_t{1}, 0, 8, "",
                "Grid steps either side of the coarse Doppler searched again by the full-rate refinement."),
      float_list_param("round_window_s", std::vector<double>{}, -10.0, 10.0, "s",
                       "Round gate (Montage protocol: every user emits once per round, a known time after the radio "
                       "start): [before_s, after_s] = other codes are searched only from before_s before to after_s "
                       "after one of this device's own emissions (speaker latency spread + largest range / c); "
                       "[] = everywhere. Needs the own emission (cancel_own).", 0, 2),
  };
  return schema;
}

const locus_plugin_descriptor* descriptor() {
  static const locus_plugin_descriptor d{
      LOCUS_PLUGIN_ABI_VERSION,
      LOCUS_PLUGIN_DETECTOR,
      "goldcode",
      "0.1.0",
      "Montage multi-user Gold-coded tone receiver: band-pass, I/Q demodulation, Pearson correlation per code",
      kInputAudio,
      &schema_fn,
      &create,
      nullptr,
  };
  return &d;
}

}  // namespace locus::plugins::goldcode
