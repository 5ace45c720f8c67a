// The `chirp` LFM matched-filter detector; algorithm, outputs and gap handling are documented in
// chirp.hpp, the parameters in docs/detectors.md.
#include "chirp.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <complex>
#include <cstdint>
#include <limits>
#include <numbers>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "locus/dsp/correlator.hpp"
#include "locus/dsp/emission_canceller.hpp"
#include "locus/dsp/peak.hpp"
#include "locus/dsp/prescreen.hpp"
#include "locus/dsp/signals.hpp"

namespace locus::plugins::chirp {

namespace {

/// The distinct lfm signals of DeviceGeometry::scene_emits, in scene order, as unit-amplitude
/// templates like those of the config (a detection's amplitude is relative to its template).
std::vector<dsp::SignalSpec> scene_lfms(std::span<const SceneSignal> scene_emits) {
  std::vector<dsp::SignalSpec> out;
  for (const SceneSignal& entry : scene_emits) {
    const SignalSpec& sig = entry.signal;
    if (sig.type != "lfm") continue;
    const bool seen = std::any_of(out.begin(), out.end(), [&](const dsp::SignalSpec& o) {
      return o.f0_hz == sig.f0_hz && o.f1_hz == sig.f1_hz && o.duration_s == sig.duration_s && o.fade_s == sig.fade_s;
    });
    if (seen) continue;
    dsp::SignalSpec s;
    s.type = "lfm";
    s.f0_hz = sig.f0_hz;
    s.f1_hz = sig.f1_hz;
    s.duration_s = sig.duration_s;
    s.fade_s = sig.fade_s;
    out.push_back(s);
  }
  return out;
}

/// Index in `specs` of the lfm the device itself emits (DeviceGeometry::emits) when no other source of
/// the scene (DeviceGeometry::scene_emits) emits the same signal; -1 when there is none. A signal that
/// another source also emits is not cancelled: its arrivals from the other source would go with it.
int own_template(const std::vector<dsp::SignalSpec>& specs, const DeviceGeometry& g, std::string_view device) {
  auto same = [](const dsp::SignalSpec& a, const SignalSpec& sig) {
    return sig.type == "lfm" && sig.f0_hz == a.f0_hz && sig.f1_hz == a.f1_hz && sig.duration_s == a.duration_s &&
           sig.fade_s == a.fade_s;
  };
  for (std::size_t t = 0; t < specs.size(); ++t) {
    const bool mine = std::any_of(g.emits.begin(), g.emits.end(), [&](const SignalSpec& sig) { return same(specs[t], sig); });
    if (!mine) continue;
    bool shared = false;
    for (const SceneSignal& e : g.scene_emits)
      if (e.id != device && same(specs[t], e.signal)) shared = true;
    if (!shared) return static_cast<int>(t);
  }
  return -1;
}

enum class Refine : std::uint8_t { Phase, Gaussian, Parabolic };

class ChirpDetector final : public Detector {
 public:
  void configure(const StreamInfo& info, const Params& params, HostContext& ctx) override {
    log_ = &ctx.log;
    device_ = info.device;
    detector_ = NameTag(ctx.instance);
    stream_ = info.stream;
    rate_ = info.sample_rate_hz;
    if (!(rate_ > 0)) throw std::runtime_error("chirp: sample rate must be > 0");
    if (info.channels == 0) throw std::runtime_error("chirp: the stream has no channels");
    channels_ = info.channels;

    // Templates: the `templates` quadruples when given, else the single f0/f1/duration/fade template.
    std::vector<dsp::SignalSpec> specs;
    const std::vector<double>& list = params.get_floats("templates");
    if (params.get_bool("from_scene") && ctx.geometry != nullptr) specs = scene_lfms(ctx.geometry->scene_emits);
    if (!specs.empty()) {
      ctx.log.info("chirp: " + std::to_string(specs.size()) + " template(s) from the scene's lfm signals");
    } else if (!list.empty()) {
      if (list.size() % 4 != 0)
        throw std::runtime_error("chirp: templates must hold f0_hz, f1_hz, duration_s, fade_s quadruples; got " +
                                 std::to_string(list.size()) + " values");
      for (std::size_t i = 0; i < list.size(); i += 4) specs.push_back(lfm(list[i], list[i + 1], list[i + 2], list[i + 3]));
    } else {
      specs.push_back(lfm(params.get_float("f0_hz"), params.get_float("f1_hz"), params.get_float("duration_s"),
                          params.get_float("fade_s")));
    }
    std::vector<std::vector<float>> templates;
    std::vector<double> bandwidth_hz;
    for (std::size_t t = 0; t < specs.size(); ++t) {
      const dsp::SignalSpec& s = specs[t];
      const std::string what = "chirp: template " + std::to_string(t) + " (" + std::to_string(s.f0_hz) + "-" +
                               std::to_string(s.f1_hz) + " Hz, " + std::to_string(s.duration_s) + " s)";
      if (!(s.duration_s > 0.0)) throw std::runtime_error(what + ": duration_s must be > 0");
      if (std::max(s.f0_hz, s.f1_hz) > rate_ / 2.0)
        throw std::runtime_error(what + ": frequencies must not exceed Nyquist (" + std::to_string(rate_ / 2.0) + " Hz)");
      if (std::fabs(s.f1_hz - s.f0_hz) < 1.0) throw std::runtime_error(what + ": f0_hz and f1_hz must differ (an LFM sweep)");
      if (2.0 * s.fade_s > s.duration_s) throw std::runtime_error(what + ": fade_s must be at most half of duration_s");
      std::vector<float> h = dsp::render_signal(s, rate_);
      if (h.size() < 8) throw std::runtime_error(what + ": shorter than 8 samples at this sample rate");
      templates.push_back(std::move(h));
      bandwidth_hz.push_back(std::fabs(s.f1_hz - s.f0_hz));
    }
    templates_ = templates.size();

    threshold_db_ = params.get_float("threshold_db");
    threshold_ = std::pow(10.0, threshold_db_ / 10.0);
    const double rho = params.get_float("min_coefficient");
    min_rho2_ = rho * rho;
    const double ratio = params.get_float("earliest_ratio");
    ratio2_ = ratio * ratio;
    window_frames_ = static_cast<std::uint64_t>(std::llround(params.get_float("earliest_window_s") * rate_));
    spacing_frames_ = static_cast<std::uint64_t>(std::llround(params.get_float("min_spacing_s") * rate_));
    prescreen_ = params.get_bool("prescreen");
    const std::string& refine = params.get_string("refine");
    refine_ = refine == "gaussian" ? Refine::Gaussian : refine == "parabolic" ? Refine::Parabolic : Refine::Phase;

    const auto fft_size = params.get_int("fft_size");
    if (fft_size != 0 && (fft_size < 0 || (fft_size & (fft_size - 1)) != 0))
      throw std::runtime_error("chirp: fft_size must be 0 (automatic) or a power of two, got " + std::to_string(fft_size));
    // Own-emission cancellation: the device's own template is searched in the raw audio (correlator
    // channel c), every other template in the audio with the own emission subtracted (channel
    // channels_ + c, fed by the canceller).
    own_ = -1;
    if (params.get_bool("cancel_own") && ctx.geometry != nullptr)
      own_ = own_template(specs, *ctx.geometry, ctx.device);
    if (own_ >= 0 && templates_ < 2) own_ = -1;  // nothing else to search for
    if (own_ >= 0) {
      dsp::EmissionCanceller::Options co;
      co.channels = channels_;
      co.taps_before = kCancelTapsBefore;
      co.taps_after = static_cast<std::size_t>(std::llround(params.get_float("cancel_fir_s") * rate_));
      try {
        canceller_.configure(templates[static_cast<std::size_t>(own_)], ctx.fft, co);
      } catch (const std::invalid_argument& e) {
        throw std::runtime_error(std::string("chirp: own-emission canceller: ") + e.what());
      }
      ctx.log.info("chirp: template " + std::to_string(own_) +
                   " is this device's own emission: searched in the raw audio, the others after subtracting it");
    }
    dsp::Correlator::Options opt;
    opt.channels = own_ >= 0 ? 2 * channels_ : channels_;
    opt.fft_size = static_cast<std::size_t>(fft_size);
    const double hop_s = params.get_float("hop_s");
    opt.hop = hop_s > 0.0 ? std::max<std::size_t>(1, static_cast<std::size_t>(std::llround(hop_s * rate_))) : 0;
    opt.analytic = true;
    opt.baseband = true;
    try {
      corr_.configure(templates, ctx.fft, opt);
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(std::string("chirp: ") + e.what());
    }
    const std::size_t n = corr_.fft_size();

    // Per template: mainlobe guard (the envelope's mainlobe is ~fs/B wide each side) and how long an
    // event keeps collecting after its strongest lag (settle_s): by default one template length plus
    // the guard, because the range sidelobes of a strong chirp (and its cross-terms with other
    // templates) reach up to a template length before the mainlobe and may open the event early; never
    // less than the multipath fit's window after the peak (3 guards).
    const double settle_s = params.get_float("settle_s");
    guard_.resize(templates_);
    span_.resize(templates_);
    std::uint64_t longest_span = 0;
    for (std::size_t t = 0; t < templates_; ++t) {
      guard_[t] = static_cast<std::uint64_t>(std::ceil(2.0 * rate_ / bandwidth_hz[t])) + 2;
      span_[t] = settle_s > 0.0 ? std::max<std::uint64_t>(static_cast<std::uint64_t>(std::llround(settle_s * rate_)),
                                                          3 * guard_[t] + 1)
                                : templates[t].size() + guard_[t];
      longest_span = std::max(longest_span, window_frames_ + span_[t] + 2 * guard_[t]);
    }
    // Multipath fit windows: [peak - guard, peak + 3 guard] (the direct path plus reflections up to
    // ~6 mainlobes later, whose skirts and sidelobes bias the composite peak).
    fits_.assign(templates_, dsp::MultipathFit{});
    std::size_t widest = 0;
    for (std::size_t t = 0; t < templates_; ++t) {
      const std::size_t w = static_cast<std::size_t>(4 * guard_[t] + 1);
      // (its autocorrelation table needs an FFT of twice the template, whatever the correlator's size)
      const std::size_t fit_n = std::max(n, std::bit_ceil(2 * templates[t].size()));
      fits_[t].configure(templates[t], fit_n, ctx.fft, corr_.centroid_omega(t), w + 2, w);
      widest = std::max(widest, w);
    }
    zwin_.assign(widest, {});
    ring_size_ = std::bit_ceil(static_cast<std::size_t>(longest_span + 16));
    ring_mask_ = ring_size_ - 1;

    tracks_.assign(channels_ * templates_, Track{});
    ring_re_.assign(channels_ * templates_ * ring_size_, 0.0f);
    ring_im_.assign(channels_ * templates_ * ring_size_, 0.0f);
    ring_pow_.assign(channels_ * templates_ * ring_size_, 0.0f);
    ring_ok_.assign(channels_ * templates_ * ring_size_, 0);
    pow_.assign(n, 0.0f);
    sorted_.assign(n, 0.0f);
    screens_.assign(channels_ * templates_, dsp::BandPrescreen{});
    const double prescreen_db = params.get_float("prescreen_db");
    for (std::size_t t = 0; t < templates_; ++t) {
      const double lo = std::min(specs[t].f0_hz, specs[t].f1_hz), hi = std::max(specs[t].f0_hz, specs[t].f1_hz);
      for (std::uint32_t c = 0; c < channels_; ++c) {
        try {
          screens_[c * templates_ + t].configure(n, rate_, lo, hi, prescreen_db);
        } catch (const std::invalid_argument& e) {
          if (prescreen_) throw std::runtime_error("chirp: template " + std::to_string(t) + ": " + e.what());
        }
      }
    }
    mode_.assign(templates_, Mode::None);
    cross_tables(templates, ctx.fft);
    origin_.assign(channels_, 0);
    started_ = false;
    expected_frame_ = 0;
    dropped_ = 0;
    windows_ = 0;
    windows_skipped_ = 0;
  }

  void process_audio(const AudioBlock& block, EventSink& out) noexcept override {
    if (!started_) {
      restart(block.first_frame);
    } else if (block.lost_before > 0 || block.first_frame != expected_frame_) {
      for (std::uint32_t c = 0; c < channels_; ++c) drain(c, out);
      restart(block.first_frame);
    }
    const std::uint32_t nch = std::min(block.channels, channels_);
    for (std::uint32_t c = 0; c < nch; ++c) {
      const float* x = block.channel_data[c];
      feed(c, c, x, block.frames, out);
      if (own_ < 0) continue;
      std::size_t pos = 0;
      while (pos < block.frames) {
        pos += canceller_.push(c, x + pos, block.frames - pos);
        if (canceller_.full(c)) {
          const std::size_t n = canceller_.process(c);
          feed(c, channels_ + c, canceller_.output(c), n, out);
          canceller_.advance(c);
        }
      }
    }
    expected_frame_ = block.first_frame + block.frames;
  }

  void finish(EventSink& out) override {
    if (started_)
      for (std::uint32_t c = 0; c < channels_; ++c) drain(c, out);
    started_ = false;
    if (dropped_ > 0 && log_)
      log_->warn("chirp: " + std::to_string(dropped_) + " detections dropped (event queue full)");
    if (log_)
      log_->debug("chirp: " + std::to_string(windows_) + " windows, " + std::to_string(windows_skipped_) +
                  " template correlations skipped by the pre-screen, " + std::to_string(explained_) +
                  " events dropped as another template's cross-correlation");
  }

 private:
  struct Track {
    double noise = 0.0;          // tracked noise power of |z|^2 (0 = none yet)
    std::uint64_t next_lag = 0;  // next lag this track will see (segment-relative)
    std::uint64_t allowed = 0;   // first lag a new event may open at (min spacing)
    bool open = false;
    std::uint64_t t0 = 0, best_lag = 0, end = 0;
    double best = 0.0;
    double thr_pow = 0.0;        // absolute threshold when the event opened
    double noise_at_open = 0.0;
    std::uint64_t valid_from = 0;  // first ring lag written in full for the open event
    bool has_last = false;         // the last reported event's strongest lag and power
    std::uint64_t last_lag = 0;
    double last_pow = 0.0;
  };
  enum class Mode : std::uint8_t { None, Skip, Full };  // a template's handling of the current window

  /// [main] cross2_: for every ordered pair (t, y), t != y, |sum_j h_y[j + tau] a_t[j]|^2 for tau in
  /// (-L_t, L_y) (index tau + L_t - 1), a_t = h_t + j H{h_t} (the analytic template: |.| is the envelope the correlator
  /// gives for a unit copy of y starting tau lags before the lag of t).
  void cross_tables(const std::vector<std::vector<float>>& templates, FftPlanner& planner) {
    const std::size_t T = templates.size();
    cross2_.assign(T * T, {});
    if (T < 2) return;
    std::vector<std::vector<double>> hil(T);
    for (std::size_t t = 0; t < T; ++t) {
      const std::vector<float>& h = templates[t];
      const std::size_t n = std::bit_ceil(2 * h.size());
      auto fft = planner.plan_real(n);
      std::vector<float> buf(n, 0.0f), outv(n, 0.0f);
      std::copy(h.begin(), h.end(), buf.begin());
      std::vector<std::complex<float>> spec(n / 2 + 1);
      fft->forward(buf.data(), spec.data());
      spec[0] = spec[n / 2] = 0.0f;
      for (std::size_t k = 1; k < n / 2; ++k) spec[k] = std::complex<float>(spec[k].imag(), -spec[k].real());  // -j
      fft->inverse(spec.data(), outv.data());
      hil[t].resize(h.size());
      for (std::size_t j = 0; j < h.size(); ++j) hil[t][j] = outv[j] / static_cast<double>(n);
    }
    for (std::size_t t = 0; t < T; ++t)
      for (std::size_t y = 0; y < T; ++y) {
        if (t == y) continue;
        const std::vector<float>& ht = templates[t];
        const std::vector<float>& hy = templates[y];
        const std::int64_t lt = static_cast<std::int64_t>(ht.size()), ly = static_cast<std::int64_t>(hy.size());
        std::vector<float>& tab = cross2_[t * T + y];
        tab.assign(static_cast<std::size_t>(lt + ly - 1), 0.0f);
        for (std::int64_t tau = -(lt - 1); tau < ly; ++tau) {
          // template t at lag k, signal y starting at m = k - tau: sample k + j is y's sample j + tau
          double re = 0.0, im = 0.0;
          const std::int64_t j0 = std::max<std::int64_t>(0, -tau), j1 = std::min<std::int64_t>(lt, ly - tau);
          for (std::int64_t j = j0; j < j1; ++j) {
            const double v = hy[static_cast<std::size_t>(j + tau)];
            re += v * ht[static_cast<std::size_t>(j)];
            im += v * hil[t][static_cast<std::size_t>(j)];
          }
          tab[static_cast<std::size_t>(tau + lt - 1)] = static_cast<float>(re * re + im * im);
        }
      }
  }

  static dsp::SignalSpec lfm(double f0, double f1, double duration, double fade) {
    dsp::SignalSpec s;
    s.type = "lfm";
    s.f0_hz = f0;
    s.f1_hz = f1;
    s.duration_s = duration;
    s.fade_s = fade;
    s.amplitude = 1.0;
    return s;
  }

  /// Correlator channel of template t for audio channel c.
  std::size_t cchan(std::uint32_t c, std::size_t t) const noexcept {
    return own_ >= 0 && static_cast<int>(t) != own_ ? channels_ + c : c;
  }

  /// Pushes n samples into correlator channel cc (audio channel c), correlating every full window.
  void feed(std::uint32_t c, std::size_t cc, const float* x, std::size_t n, EventSink& out) noexcept {
    std::size_t pos = 0;
    while (pos < n) {
      pos += corr_.push(cc, x + pos, n - pos);
      if (corr_.full(cc)) {
        corr_.transform(cc);
        window_transformed(c, cc, corr_.hop(), out);
        corr_.advance(cc);
      }
    }
  }

  void restart(std::uint64_t first_frame) noexcept {
    for (std::uint32_t c = 0; c < channels_; ++c) {
      corr_.reset(c, 0);
      if (own_ >= 0) {
        corr_.reset(channels_ + c, 0);
        canceller_.reset(c, 0);
      }
      origin_[c] = first_frame;
      for (std::size_t t = 0; t < templates_; ++t) {
        Track& tr = track(c, t);
        tr.next_lag = 0;
        tr.allowed = 0;
        tr.open = false;
        tr.has_last = false;
      }
    }
    started_ = true;
  }

  /// Correlates what is left of channel c's contiguous audio and closes its open events.
  void drain(std::uint32_t c, EventSink& out) noexcept {
    const std::size_t valid = corr_.flush(c);
    if (valid > 0) window_transformed(c, c, valid, out);
    if (own_ >= 0) {
      const std::size_t n = canceller_.flush(c);
      feed(c, channels_ + c, canceller_.output(c), n, out);
      canceller_.reset(c, 0);
      const std::size_t v = corr_.flush(channels_ + c);
      if (v > 0) window_transformed(c, channels_ + c, v, out);
    }
    for (std::size_t t = 0; t < templates_; ++t) {
      Track& tr = track(c, t);
      if (tr.open) finalize(c, t, out);
    }
  }

  /// Correlates the transformed window of correlator channel cc (audio channel c) with the templates
  /// searched there and scans lags [window_start, window_start + count).
  void window_transformed(std::uint32_t c, std::size_t cc, std::size_t count, EventSink& out) noexcept {
    ++windows_;
    const std::uint64_t base = corr_.window_start(cc);
    // Pass 1: which templates need the full-rate correlation (each keeps its own output buffer), so
    // that an event of one template finalized in pass 2 can see where the others are strong in this
    // window (the wrong-template check, explained_by_other()).
    for (std::size_t t = 0; t < templates_; ++t) {
      mode_[t] = Mode::None;
      if (cchan(c, t) != cc) continue;
      dsp::BandPrescreen& screen = screens_[c * templates_ + t];
      if (prescreen_ && !screen.pass(corr_.spectrum())) {
        ++windows_skipped_;
        mode_[t] = Mode::Skip;
        screen.note_quiet(true);
        continue;
      }
      // Quiet windows (nearly all) are screened on the decimated complex-baseband correlation; the
      // full-rate correlation and scan run only where something may cross the threshold.
      if (count == corr_.hop() && !track(c, t).open && corr_.baseband_decimation(t) > 1 &&
          quiet_baseband(c, t, base, count)) {
        if (prescreen_) screen.note_quiet(false);
        continue;
      }
      corr_.correlate(t);
      mode_[t] = Mode::Full;
    }
    win_base_ = base;
    win_count_ = count;
    for (std::size_t t = 0; t < templates_; ++t) {
      if (mode_[t] == Mode::Skip) {
        skip(c, t, base, count, out);
      } else if (mode_[t] == Mode::Full) {
        const bool crossed = scan(c, cc, t, base, count, out);
        if (prescreen_ && !crossed) screens_[c * templates_ + t].note_quiet(false);
      }
    }
    for (std::size_t t = 0; t < templates_; ++t) mode_[t] = Mode::None;
  }

  /// True when the power pk of template t's path at lag k is explained by a strong arrival of
  /// another template searched in the same audio: its range cross-correlation with t (precomputed,
  /// cross2_) at that lag offset, scaled by the other arrival's amplitude, is within kExplained of pk.
  /// Evidence: the other template's open or last event, and its full-rate correlation in the window
  /// being scanned (local maxima above its threshold).
  bool explained_by_other(std::uint32_t c, std::size_t t, std::uint64_t k, double pk) const noexcept {
    if (templates_ < 2) return false;
    const std::size_t lt = corr_.template_length(t);
    for (std::size_t y = 0; y < templates_; ++y) {
      if (y == t || cchan(c, y) != cchan(c, t)) continue;
      const std::vector<float>& table = cross2_[t * templates_ + y];
      const std::size_t ly = corr_.template_length(y);
      const double ey2 = corr_.template_energy(y) * corr_.template_energy(y);
      auto predicted = [&](std::uint64_t m, double py) {
        // tau = k - m in (-lt, ly): table index tau + lt - 1
        const std::int64_t tau = static_cast<std::int64_t>(k) - static_cast<std::int64_t>(m);
        if (tau <= -static_cast<std::int64_t>(lt) || tau >= static_cast<std::int64_t>(ly)) return 0.0;
        return py / ey2 * table[static_cast<std::size_t>(tau + static_cast<std::int64_t>(lt) - 1)];
      };
      double pred = 0.0;
      const Track& ty = tracks_[c * templates_ + y];
      if (ty.open) pred = std::max(pred, predicted(ty.best_lag, ty.best));
      if (ty.has_last) pred = std::max(pred, predicted(ty.last_lag, ty.last_pow));
      if (mode_[y] == Mode::Full) {
        const float* re = corr_.real(y);
        const float* im = corr_.imag(y);
        const double thr = std::max(ty.noise, std::numeric_limits<double>::min()) * threshold_;
        const std::uint64_t lo = std::max<std::uint64_t>(win_base_ + 1, k + 1 > ly ? k + 1 - ly : 0);
        const std::uint64_t hi = std::min<std::uint64_t>(win_base_ + win_count_ - 1, k + lt);
        for (std::uint64_t m = lo; m < hi; ++m) {
          const std::size_t i = static_cast<std::size_t>(m - win_base_);
          const double p = re[i] * re[i] + im[i] * im[i];
          if (p < thr) continue;
          const double pm = re[i - 1] * re[i - 1] + im[i - 1] * im[i - 1];
          const double pp = re[i + 1] * re[i + 1] + im[i + 1] * im[i + 1];
          if (p >= pm && p >= pp) pred = std::max(pred, predicted(m, p));
        }
      }
      if (pk < kExplained * pred) return true;
    }
    return false;
  }

  /// Lags [base, base + count) of a window the pre-screen skipped: nothing above the noise.
  void skip(std::uint32_t c, std::size_t t, std::uint64_t base, std::size_t count, EventSink& out) noexcept {
    Track& tr = track(c, t);
    const std::size_t r0 = (c * templates_ + t) * ring_size_;
    for (std::size_t i = 0; i < count; ++i) {
      const std::uint64_t lag = base + i;
      const std::size_t r = r0 + (lag & ring_mask_);
      ring_re_[r] = ring_im_[r] = ring_pow_[r] = 0.0f;
      ring_ok_[r] = 0;
      tr.next_lag = lag + 1;
      if (tr.open && lag > tr.end) finalize(c, t, out);
    }
  }

  /// Lags [base, base + count) of a full window on template t's decimated baseband correlation: when
  /// no decimated lag reaches the threshold times the template's worst between-lag loss (so no lag
  /// in between can cross it either), does what scan()'s fast path does and returns true; else
  /// returns false (nothing changed) and the caller scans the full-rate correlation.
  bool quiet_baseband(std::uint32_t c, std::size_t t, std::uint64_t base, std::size_t count) noexcept {
    Track& tr = track(c, t);
    corr_.correlate_baseband(t);
    const std::size_t d = corr_.baseband_decimation(t);
    const std::complex<float>* z = corr_.baseband(t);
    const std::size_t nm = (count + d - 1) / d;  // decimated lags m d < count
    float* pw = pow_.data();
    float pmax = 0.0f;
    for (std::size_t m = 0; m < nm; ++m) {
      pw[m] = std::norm(z[m]);
      pmax = std::max(pmax, pw[m]);
    }
    // The same noise estimate as scan(): the median over every kNoiseStride-th lag of the window's
    // whole span (lookback: overlapped windows).
    const std::size_t step = kNoiseStride / d;
    std::size_t k = 0;
    {
      const std::size_t back = corr_.lookback(cchan(c, t)) / d;
      for (std::size_t m = 0; m < back + nm; m += step) sorted_[k++] = std::norm(z[static_cast<std::ptrdiff_t>(m) - static_cast<std::ptrdiff_t>(back)]);
    }
    const auto mid = sorted_.begin() + static_cast<std::ptrdiff_t>(k / 2);
    std::nth_element(sorted_.begin(), mid, sorted_.begin() + static_cast<std::ptrdiff_t>(k));
    const double p_window = static_cast<double>(*mid) / std::numbers::ln2;
    const double noise = std::max({tr.noise, p_window, std::numeric_limits<double>::min()});
    const double thr = noise * threshold_;
    if (pmax > kBasebandMargin * corr_.baseband_peak_ratio(t) * thr) return false;
    const std::uint64_t lag = base + count - 1;
    const std::size_t r = (c * templates_ + t) * ring_size_ + (lag & ring_mask_);
    const std::complex<float> zl = corr_.baseband_lag(t, count - 1);
    ring_re_[r] = zl.real();
    ring_im_[r] = zl.imag();
    ring_pow_[r] = std::norm(zl);
    ring_ok_[r] = 0;
    tr.next_lag = base + count;
    tr.noise = tr.noise > 0.0 ? 0.5 * (tr.noise + p_window) : p_window;
    return true;
  }

  /// Scans lags [base, base + count) of template t's correlation; true if any crossed the threshold.
  bool scan(std::uint32_t c, std::size_t cc, std::size_t t, std::uint64_t base, std::size_t count,
            EventSink& out) noexcept {
    Track& tr = track(c, t);
    const float* re = corr_.real(t);
    const float* im = corr_.imag(t);
    float* pw = pow_.data();
    float pmax = 0.0f;
    for (std::size_t i = 0; i < count; ++i) {
      pw[i] = re[i] * re[i] + im[i] * im[i];
      pmax = std::max(pmax, pw[i]);
    }
    // Noise power from the median of |z|^2 (exponential for Gaussian noise: median = P ln 2), taken
    // over every 4th lag (neighbouring lags of a band-limited output are correlated anyway) of the
    // window's whole span: with overlapped windows (hop_s) also the lags earlier windows output, else
    // a short window inside a loud chirp's sidelobes would take them for noise.
    std::size_t m = 0;
    {
      const std::size_t back = corr_.lookback(cc);
      const float* re0 = re - back;
      const float* im0 = im - back;
      for (std::size_t i = 0; i < back + count; i += kNoiseStride) sorted_[m++] = re0[i] * re0[i] + im0[i] * im0[i];
    }
    const auto mid = sorted_.begin() + static_cast<std::ptrdiff_t>(m / 2);
    std::nth_element(sorted_.begin(), mid, sorted_.begin() + static_cast<std::ptrdiff_t>(m));
    const double p_window = static_cast<double>(*mid) / std::numbers::ln2;
    const double noise = std::max({tr.noise, p_window, std::numeric_limits<double>::min()});
    const double thr = noise * threshold_;

    bool crossed = false;
    const std::size_t r0 = (c * templates_ + t) * ring_size_;
    if (!tr.open && !(pmax > thr)) {
      // Fast path (nearly every window): nothing to report. An event opening in a later window looks
      // back at most one lag before its opening, so only the last lag goes into the ring.
      if (count > 0) {
        const std::uint64_t lag = base + count - 1;
        const std::size_t r = r0 + (lag & ring_mask_);
        ring_re_[r] = re[count - 1];
        ring_im_[r] = im[count - 1];
        ring_pow_[r] = pw[count - 1];
        ring_ok_[r] = 0;
      }
      tr.next_lag = base + count;
      tr.noise = tr.noise > 0.0 ? 0.5 * (tr.noise + p_window) : p_window;
      return false;
    }
    // Energy of the input under each lag (running sum over the template length) for the correlation
    // coefficient rho^2 = |z|^2 / (sum h^2 * sum x^2): ~1 for a matching chirp, ~2/L for noise, and
    // small for the range sidelobes of a loud chirp and its cross-terms with other templates.
    const float* xs = corr_.samples(cc);
    const std::size_t len = corr_.template_length(t);
    const double eh = corr_.template_energy(t);
    // Computed lazily (only lags above the threshold need it): slid forward from the last lag it was
    // computed at, or summed afresh when that is more than a template length back.
    double ex = 0.0;
    std::size_t ex_at = 0;
    bool have_ex = false;
    auto energy_at = [&](std::size_t i) {
      if (!have_ex || i - ex_at > len) {
        ex = 0.0;
        for (std::size_t j = i; j < i + len; ++j) ex += static_cast<double>(xs[j]) * xs[j];
        have_ex = true;
      } else {
        for (std::size_t j = ex_at + 1; j <= i; ++j) {
          const double a = xs[j - 1], b = xs[j + len - 1];
          ex += b * b - a * a;
        }
      }
      ex_at = i;
      return ex;
    };
    for (std::size_t i = 0; i < count; ++i) {
      const std::uint64_t lag = base + i;
      const std::size_t r = r0 + (lag & ring_mask_);
      const double p = pw[i];
      // Digital silence (a JACK dummy port, a file padded with zeros) has no noise floor: there the
      // threshold is ~0 and the FFT's round-off leaks above it, and rho would pass trivially on
      // zero input energy. Require real input under the lag (above -120 dBFS over the template).
      const double ex_i = p > thr ? energy_at(i) : 0.0;
      const bool ok = p > thr && ex_i > kMinWindowEnergy && p >= min_rho2_ * eh * ex_i;
      ring_re_[r] = re[i];
      ring_im_[r] = im[i];
      ring_pow_[r] = pw[i];
      ring_ok_[r] = ok ? 1 : 0;
      tr.next_lag = lag + 1;
      if (tr.open && lag > tr.end) finalize(c, t, out);
      if (p > thr) crossed = true;
      if (ok) {
        if (!tr.open && lag >= tr.allowed) {
          tr.open = true;
          tr.t0 = lag;
          tr.valid_from = base;  // this window's lags all went into the ring
          tr.best = p;
          tr.best_lag = lag;
          tr.thr_pow = thr;
          tr.noise_at_open = noise;
          tr.end = std::max(lag + window_frames_, lag + span_[t]);
        }
      }
      if (ok && tr.open && p > tr.best) {
        tr.best = p;
        tr.best_lag = lag;
        tr.end = std::max(tr.t0 + window_frames_, lag + span_[t]);
      }
    }
    if (!crossed) tr.noise = tr.noise > 0.0 ? 0.5 * (tr.noise + p_window) : p_window;
    return crossed;
  }

  /// Reports the earliest qualifying path of track (c, t)'s open event and closes it.
  void finalize(std::uint32_t c, std::size_t t, EventSink& out) noexcept {
    Track& tr = track(c, t);
    tr.open = false;
    const std::size_t r0 = (c * templates_ + t) * ring_size_;
    auto pow_at = [&](std::uint64_t lag) -> double {
      // Only lags already written and not yet overwritten; anything else counts as 0.
      if (lag >= tr.next_lag || lag + ring_size_ < tr.next_lag) return 0.0;
      return ring_pow_[r0 + (lag & ring_mask_)];
    };
    const double need = std::max(tr.thr_pow, ratio2_ * tr.best);
    // An event whose strongest path is only the range cross-correlation of another template's strong
    // arrival (the wrong template's sidelobe) is not reported.
    if (explained_by_other(c, t, tr.best_lag, tr.best)) {
      ++explained_;
      tr.allowed = tr.best_lag + 1;
      return;
    }
    std::uint64_t k = tr.best_lag;
    const std::uint64_t from = std::max(tr.t0, tr.best_lag > window_frames_ ? tr.best_lag - window_frames_ : 0);
    for (std::uint64_t j = from; j <= tr.best_lag; ++j) {
      const double p = pow_at(j);
      if (p < need || !ring_ok_[r0 + (j & ring_mask_)]) continue;
      const double before = j > 0 ? pow_at(j - 1) : 0.0;
      const double after = j + 1 <= tr.end ? pow_at(j + 1) : 0.0;
      if (p >= before && p >= after && (j == tr.best_lag || !explained_by_other(c, t, j, p))) {
        k = j;
        break;
      }
    }
    const double pk = pow_at(k);
    const double am = std::sqrt(k > 0 ? pow_at(k - 1) : 0.0), a0 = std::sqrt(pk), ap = std::sqrt(pow_at(k + 1));
    const dsp::PeakFit fit = refine_ == Refine::Parabolic ? dsp::parabolic_peak(am, a0, ap) : dsp::gaussian_peak(am, a0, ap);
    double lag = static_cast<double>(k) + fit.offset;
    double envelope_lag = lag;
    double margin = 1.0;  // how firmly the carrier cycle was chosen (multipath fit), scales confidence
    if (refine_ == Refine::Phase) {
      // The envelope maximum of the band-limited baseband (dsp::analytic_peak) picks the carrier
      // cycle, the phase the fraction within it; without the 7 lags around k, a 3-point fit does.
      const std::uint64_t oldest = std::min(tr.valid_from, tr.t0 > 0 ? tr.t0 - 1 : 0);
      const bool have7 = k >= oldest + 3 && k + 3 < tr.next_lag && k + ring_size_ >= tr.next_lag + 3;
      if (have7) {
        std::array<std::complex<float>, 7> z7;
        for (std::size_t i = 0; i < 7; ++i) {
          const std::size_t ri = r0 + ((k - 3 + i) & ring_mask_);
          z7[i] = {ring_re_[ri], ring_im_[ri]};
        }
        const dsp::AnalyticPeak ap = dsp::analytic_peak(z7.data(), z7.size(), 3, corr_.centroid_omega(t));
        lag = static_cast<double>(k) + ap.delay;
        envelope_lag = static_cast<double>(k) + ap.envelope;
      } else {
        const double coarse = fit.offset;
        const std::int64_t step = coarse > 0.5 ? 1 : coarse < -0.5 ? -1 : 0;
        const std::uint64_t k1 = static_cast<std::uint64_t>(static_cast<std::int64_t>(k) + step);
        const std::size_t r = r0 + (k1 & ring_mask_);
        const double d = dsp::phase_refine_near(ring_re_[r], ring_im_[r], corr_.centroid_omega(t),
                                                coarse - static_cast<double>(step));
        lag = static_cast<double>(k1) + d;
      }
      // Unless the window around the peak is not a single path: then the cycle comes from the
      // direct path of a multipath fit (dsp::MultipathFit). Lags before the window the event opened in
      // (valid_from) may be stale.
      const std::uint64_t g = guard_[t];
      const std::uint64_t lo = std::max(k > g ? k - g : 0, std::min(tr.valid_from, tr.t0 > 0 ? tr.t0 - 1 : 0));
      const std::uint64_t hi = std::min({k + 3 * g, tr.next_lag - 1, lo + zwin_.size() - 1});
      if (k >= lo && hi >= k + 2) {
        const std::size_t count = static_cast<std::size_t>(hi - lo + 1);
        for (std::size_t i = 0; i < count; ++i) {
          const std::size_t ri = r0 + ((lo + i) & ring_mask_);
          zwin_[i] = {ring_re_[ri], ring_im_[ri]};
        }
        const dsp::MultipathFit::Result m =
            fits_[t].fit(zwin_.data(), count, static_cast<std::size_t>(k - lo), tr.noise_at_open, tr.thr_pow, ratio2_);
        if (m.multipath) {
          // Move to another carrier cycle only on clear evidence: the fitted direct path lies nearer
          // another cycle of the phase estimate, the paths found explain the window (converged) and
          // the direct path's envelope and phase estimates agree (margin).
          // Otherwise keep the envelope-peak choice; a disagreement still lowers the confidence.
          const double period = 2.0 * std::numbers::pi / corr_.centroid_omega(t);
          const double cycles = std::round((static_cast<double>(lo) + m.envelope_delay - lag) / period);
          if (cycles != 0.0 && m.converged && m.margin >= kMinCycleMargin) lag = static_cast<double>(lo) + m.delay;
          margin = cycles != 0.0 ? (m.converged ? m.margin : 0.5 * m.margin) : 1.0;
        }
      }
    }
    AudioDetection d;
    d.device = device_;
    d.detector = detector_;
    d.stream = stream_;
    d.channel = static_cast<std::uint16_t>(c);
    d.template_index = static_cast<std::uint16_t>(t);
    d.frame = static_cast<double>(origin_[c]) + lag;
    d.envelope_frame = static_cast<double>(origin_[c]) + envelope_lag;
    d.carrier_period = refine_ == Refine::Phase ? static_cast<float>(2.0 * std::numbers::pi / corr_.centroid_omega(t)) : 0.0f;
    d.sample_rate_hz = rate_;
    const double snr_db = std::min(300.0, 10.0 * std::log10(std::max(fit.value * fit.value, pk) / tr.noise_at_open));
    d.snr_db = static_cast<float>(snr_db);
    d.confidence =
        static_cast<float>(margin * std::clamp(1.0 - std::pow(10.0, -(snr_db - threshold_db_) / 10.0), 0.0, 1.0));
    d.amplitude = static_cast<float>(std::max(fit.value, a0) / corr_.template_energy(t));
    if (!out.emit(Event{d})) ++dropped_;
    tr.allowed = k + spacing_frames_;
    tr.has_last = true;
    tr.last_lag = tr.best_lag;
    tr.last_pow = tr.best;
  }

  static constexpr std::size_t kNoiseStride = 4;  // a multiple of every baseband decimation (4, 2)
  static constexpr double kMinWindowEnergy = 1e-12;  // sum of x^2 under the template: digital silence
  // Extra margin (-3 dB) of the baseband screen for noise and interference between decimated lags.
  static constexpr double kBasebandMargin = 0.5;
  static constexpr double kMinCycleMargin = 0.3;  // multipath fit: agreement needed to change cycle
  static constexpr std::size_t kCancelTapsBefore = 4;  // canceller FIR taps before the integer start
  // A path weaker than this multiple of another template's predicted cross-term is that cross-term.
  static constexpr double kExplained = 4.0;  // 6 dB

  Track& track(std::uint32_t c, std::size_t t) noexcept { return tracks_[c * templates_ + t]; }

  Logger* log_ = nullptr;
  DeviceId device_;
  NameTag detector_;
  std::uint32_t stream_ = 0;
  std::uint32_t channels_ = 0;
  std::size_t templates_ = 0;
  double rate_ = 44100.0;
  double threshold_db_ = 15.0;
  double threshold_ = 1.0;
  double ratio2_ = 0.0;
  double min_rho2_ = 0.0;
  std::uint64_t window_frames_ = 0;
  std::uint64_t spacing_frames_ = 0;
  bool prescreen_ = true;
  Refine refine_ = Refine::Phase;
  dsp::Correlator corr_;
  std::vector<std::vector<float>> cross2_;  // [t * T + y]: |analytic xcorr of signal y with template t|^2 by tau
  std::vector<Mode> mode_;
  std::uint64_t win_base_ = 0, explained_ = 0;
  std::size_t win_count_ = 0;
  int own_ = -1;                      // template the device emits itself (cancelled for the others), -1 = none
  dsp::EmissionCanceller canceller_;  // removes it from the audio the other templates are searched in
  std::vector<std::uint64_t> guard_;
  std::vector<std::uint64_t> span_;
  std::size_t ring_size_ = 0, ring_mask_ = 0;
  std::vector<Track> tracks_;
  std::vector<float> ring_re_, ring_im_, ring_pow_;
  std::vector<std::uint8_t> ring_ok_;  // the lag passes the correlation-coefficient test
  std::vector<float> pow_, sorted_;
  std::vector<dsp::MultipathFit> fits_;          // per template
  std::vector<std::complex<float>> zwin_;        // the window a fit sees
  std::vector<dsp::BandPrescreen> screens_;
  std::vector<std::uint64_t> origin_;
  bool started_ = false;
  std::uint64_t expected_frame_ = 0;
  std::uint64_t dropped_ = 0;
  std::uint64_t windows_ = 0;
  std::uint64_t windows_skipped_ = 0;
};

const ParamSchema* schema_fn() { return &schema(); }
Detector* create() { return new ChirpDetector(); }

}  // namespace

const ParamSchema& schema() {
  static const ParamSchema schema = [] {
    ParamSchema s = {
        float_param("f0_hz", 2000.0, 1.0, 96000.0, "Hz", "Start frequency of the LFM template (TUM: 2 kHz; AMIL: 18 kHz)."),
        float_param("f1_hz", 8000.0, 1.0, 96000.0, "Hz", "End frequency of the LFM template (TUM: 8 kHz; AMIL: 22 kHz)."),
        float_param("duration_s", 0.040, 1e-4, 2.0, "s", "Duration of the LFM template (TUM: 40 ms; AMIL: 50 ms)."),
        float_param("fade_s", 0.005, 0.0, 1.0, "s", "Raised-cosine fade in and out of the template (as the emitter's `fade`)."),
        bool_param("from_scene", false,
                   "Take the templates from the scene: every distinct lfm signal a device or emitter of the scene "
                   "emits, in scene order (template_index = position). When the host knows no scene signals (a "
                   "live node) or the scene has no lfm, templates / f0_hz..fade_s apply."),
    };
    s.push_back(float_list_param("templates", std::vector<double>{}, 0.0, 96000.0, "",
                                 "Several templates: flat list of f0_hz, f1_hz, duration_s, fade_s quadruples "
                                 "(template_index = position); when not empty it replaces f0_hz/f1_hz/duration_s/fade_s."));
    s.push_back(float_param("threshold_db", 15.0, 3.0, 100.0, "dB",
                      "Detection threshold: envelope peak power of the correlation over its noise power."));
    s.push_back(float_param("min_coefficient", 0.2, 0.0, 1.0, "",
                      "Minimum correlation coefficient |z| / (|h| |x|) over the template length (AMIL's r): "
                      "rejects range sidelobes and cross-terms of loud chirps."));
    s.push_back(float_param("earliest_ratio", 0.35, 0.05, 1.0, "",
                      "Report the earliest envelope peak >= this fraction of the strongest one in the window "
                      "(1 = the strongest only)."));
    s.push_back(float_param("earliest_window_s", 0.010, 0.0, 1.0, "s",
                      "How long after the first threshold crossing a stronger (later) path may still arrive."));
    s.push_back(float_param("min_spacing_s", 0.1, 0.0, 60.0, "s",
                      "Minimum time between two detections of one template on one channel (suppresses echoes)."));
    s.push_back(bool_param("prescreen", true,
                           "Skip the correlation of windows without energy in the chirp's band (AMIL's FFT pre-screen)."));
    s.push_back(float_param("prescreen_db", 1.0, 0.0, 60.0, "dB",
                      "Pre-screen: in-band over out-of-band power per bin, above its quiet baseline, needed to correlate."));
    s.push_back(int_param("fft_size", std::int64_t{0}, 0, 1 << 22, "",
                          "Overlap-save FFT size (a power of two larger than the longest template); 0 = 4x the "
                          "longest template."));
    s.push_back(float_param("hop_s", 0.0, 0.0, 10.0, "s",
                      "Lags correlated per FFT window; 0 = the whole window (fft_size minus the template "
                      "length). Shorter overlaps the windows: a detection follows its arrival's end by at most "
                      "about this long (live latency), for proportionally more work."));
    s.push_back(float_param("settle_s", 0.0, 0.0, 10.0, "s",
                      "How long an event keeps collecting after its strongest lag before it is reported "
                      "(at least 3 mainlobe widths); 0 = one template length plus a mainlobe width, which "
                      "overlapping templates need (a stronger chirp's range sidelobes and cross-terms precede "
                      "its mainlobe by up to a template length). A live localizer whose arrivals never overlap "
                      "(AMIL) can shorten it to cut latency."));
    s.push_back(bool_param("cancel_own", true,
                           "When the device itself emits one of the templates (its scene `emits`) and no other "
                           "source emits the same signal: search that template in the raw audio and every other "
                           "template in the audio with the device's own emission removed (fitted subtraction, "
                           "dsp::EmissionCanceller)."));
    s.push_back(float_param("cancel_fir_s", 0.0005, 0.0, 0.02, "s",
                      "Own-emission canceller: length of the fitted speaker-to-microphone response after the "
                      "direct path (transducers, earliest reflections)."));
    s.push_back(enum_param("refine", std::string("phase"), {"phase", "gaussian", "parabolic"},
                           "Sub-sample timing: envelope fit then carrier phase (phase), or the envelope fit alone."));
    return s;
  }();
  return schema;
}

const locus_plugin_descriptor* descriptor() {
  static const locus_plugin_descriptor d{
      LOCUS_PLUGIN_ABI_VERSION,
      LOCUS_PLUGIN_DETECTOR,
      "chirp",
      "0.1.0",
      "LFM chirp matched filter (overlap-save FFT, many templates), earliest path, sub-sample timing",
      kInputAudio,
      &schema_fn,
      &create,
      nullptr,
  };
  return &d;
}

}  // namespace locus::plugins::chirp
