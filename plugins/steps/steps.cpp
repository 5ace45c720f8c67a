// The `steps` plugin (algorithms and their sources in steps.hpp).
#include "steps.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <memory>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "locus/dsp/dtw.hpp"
#include "locus/dsp/iir.hpp"
#include "motion_common/motion_common.hpp"

namespace locus::plugins::steps {

namespace {

constexpr double kGravity = 9.80665;

class StepsDetector final : public Detector {
 public:
  void configure(const StreamInfo& info, const Params& p, HostContext& ctx) override {
    log_ = &ctx.log;
    device_ = info.device.empty() ? DeviceId(ctx.device) : info.device;
    detector_ = NameTag(ctx.instance);
    tracker_.configure(p);
    spyloc_ = p.get_string("mode") == "spyloc";
    bounce_ = p.get_string("stride_model") == "bounce";
    rate_ = p.get_float("grid_rate_hz");
    dt_ = 1.0 / rate_;
    const double lp_hz = p.get_float("lowpass_hz");
    if (lp_hz >= 0.5 * rate_)
      throw std::runtime_error("steps: lowpass_hz (" + std::to_string(lp_hz) + ") must be below half of grid_rate_hz (" +
                               std::to_string(rate_) + ")");
    lp_ = dsp::SosFilter(dsp::butter_lowpass(static_cast<int>(p.get_int("lowpass_order")), lp_hz, rate_));
    mean_tc_s_ = p.get_float("mean_time_constant_s");
    min_step_s_ = p.get_float("min_step_s");
    max_step_s_ = p.get_float("max_step_s");
    if (min_step_s_ >= max_step_s_)
      throw std::runtime_error("steps: min_step_s (" + std::to_string(min_step_s_) + ") must be below max_step_s (" +
                               std::to_string(max_step_s_) + ")");
    thr_ = p.get_float("min_peak_valley_mps2");
    secondary_ratio_ = p.get_float("secondary_ratio");
    secondary_early_ = p.get_float("secondary_early");
    stride_a_ = p.get_float("stride_a");
    stride_b_ = p.get_float("stride_b");
    leg_m_ = p.get_float("leg_length_m");
    bounce_k_ = p.get_float("bounce_k");
    warmup_n_ = static_cast<std::uint64_t>(std::ceil(p.get_float("warmup_s") * rate_));

    // Band-pass bank over the walking frequencies of min/max step duration, 6 % apart.
    const int bp_order = static_cast<int>(p.get_int("bandpass_order"));
    bank_.clear();
    centers_.clear();
    for (double f = 1.0 / max_step_s_; f <= 1.0 / min_step_s_ * 1.0001; f *= 1.06) {
      if (1.5 * f >= 0.45 * rate_) break;
      centers_.push_back(f);
      bank_.emplace_back(dsp::butter_bandpass(bp_order, 0.75 * f, 1.5 * f, rate_));
    }
    if (bank_.empty()) throw std::runtime_error("steps: grid_rate_hz is too low for the walking band-pass filters");

    m_min_ = std::max<std::size_t>(2, static_cast<std::size_t>(std::lround(min_step_s_ * rate_)));
    m_max_ = std::max<std::size_t>(m_min_ + 1, static_cast<std::size_t>(std::lround(max_step_s_ * rate_)));
    ring_size_ = std::bit_ceil(4 * m_max_ + 16);
    ring_mask_ = ring_size_ - 1;
    lp_ring_.assign(ring_size_, 0.0f);
    bank_ring_.assign(bank_.size() * ring_size_, 0.0f);
    scratch_v_.assign(2 * m_max_ + 2, 0.0);
    scratch_p_.assign(2 * m_max_ + 2, 0.0);

    // SpyLoc template and DTW.
    dtw_threshold_ = p.get_float("dtw_threshold");
    dtw_window_ = static_cast<std::size_t>(std::lround(p.get_float("dtw_window_s") * rate_));
    hop_ = std::max<std::size_t>(1, static_cast<std::size_t>(std::lround(p.get_float("search_hop_s") * rate_)));
    min_std_ = p.get_float("min_accel_std_mps2");
    const std::size_t n = std::max<std::size_t>(4, static_cast<std::size_t>(std::lround(p.get_float("template_s") * rate_)));
    const std::vector<double>& user = p.get_floats("template");
    if (!user.empty() && user.size() < 4) throw std::runtime_error("steps: `template` needs at least 4 values");
    template_.assign(n, 0.0f);
    for (std::size_t i = 0; i < n; ++i) {
      if (user.empty()) {
        template_[i] = static_cast<float>(std::cos(2.0 * std::numbers::pi * static_cast<double>(i) / static_cast<double>(n)));
      } else {
        const double pos = static_cast<double>(i) * static_cast<double>(user.size() - 1) / static_cast<double>(n - 1);
        const std::size_t j = std::min(static_cast<std::size_t>(pos), user.size() - 2);
        const double fr = pos - static_cast<double>(j);
        template_[i] = static_cast<float>(user[j] + (user[j + 1] - user[j]) * fr);
      }
    }
    if (!zscore(template_.data(), template_.size()))
      throw std::runtime_error("steps: `template` is constant (it needs a shape to match)");
    window_.assign(m_max_, 0.0f);
    dtw_ = std::make_unique<dsp::Dtw>(std::max(n, m_max_) + 1);

    dropped_ = 0;
    restart();
  }

  void process_imu(const ImuSample* samples, std::size_t count, EventSink& out) noexcept override {
    for (std::size_t i = 0; i < count; ++i) {
      const ImuSample& s = samples[i];
      if (!tracker_.update(s)) continue;
      const Eigen::Vector3d a(s.accel_mps2[0], s.accel_mps2[1], s.accel_mps2[2]);
      const double av = (tracker_.q() * a).z() - kGravity;
      if (tracker_.restarted()) {
        restart();
        prev_t_ = s.t_s;
        prev_v_ = av;
        grid_t0_ = s.t_s;
        lp_.set_steady_state(av);
        for (auto& f : bank_) f.reset();
        push_grid(av, out);
        continue;
      }
      const double span = s.t_s - prev_t_;
      for (double tg = grid_time(n_); tg <= s.t_s; tg = grid_time(n_)) {
        const double v = span > 0 ? prev_v_ + (av - prev_v_) * (tg - prev_t_) / span : av;
        push_grid(v, out);
      }
      prev_t_ = s.t_s;
      prev_v_ = av;
    }
  }

  void finish(EventSink&) override {
    if (!log_) return;
    if (dropped_ > 0) log_->warn("steps: " + std::to_string(dropped_) + " Step events dropped (queue full)");
    if (tracker_.rejected() > 0)
      log_->warn("steps: " + std::to_string(tracker_.rejected()) + " IMU samples with non-finite values ignored");
    if (tracker_.gaps() > 0)
      log_->info("steps: " + std::to_string(tracker_.gaps()) + " gaps in the IMU stream restarted the detector");
    if (secondary_rejected_ > 0)
      log_->info("steps: " + std::to_string(secondary_rejected_) + " weak early peaks taken as gait harmonics, not steps");
  }

 private:
  enum class Phase { Unknown, Above, Below };

  double grid_time(std::uint64_t k) const noexcept { return grid_t0_ + static_cast<double>(k) * dt_; }

  void restart() noexcept {
    n_ = 0;
    mean_ = 0.0;
    phase_ = Phase::Unknown;
    have_peak_ = false;
    have_last_ = false;
    n_amp_ = n_int_ = 0;
    w_ = 0;
    active_ = nearest_center(1.8);
  }

  std::size_t nearest_center(double f) const noexcept {
    std::size_t best = 0;
    for (std::size_t k = 1; k < centers_.size(); ++k)
      if (std::abs(std::log(centers_[k] / f)) < std::abs(std::log(centers_[best] / f))) best = k;
    return best;
  }

  /// The band whose output the stride integrates: the one nearest this step's frequency (Montage
  /// switches its filter when the frequency moves; here every band runs, so the switch costs no
  /// settling).
  void track_frequency(double f) noexcept { active_ = nearest_center(f); }

  static bool zscore(float* x, std::size_t n) noexcept {
    double m = 0, s = 0;
    for (std::size_t i = 0; i < n; ++i) m += x[i];
    m /= static_cast<double>(n);
    for (std::size_t i = 0; i < n; ++i) s += (x[i] - m) * (x[i] - m);
    s = std::sqrt(s / static_cast<double>(n));
    if (!(s > 1e-12)) return false;
    for (std::size_t i = 0; i < n; ++i) x[i] = static_cast<float>((x[i] - m) / s);
    return true;
  }

  void push_grid(double v, EventSink& out) noexcept {
    const double y = lp_.process_double(v);
    const std::uint64_t k = n_++;
    for (std::size_t b = 0; b < bank_.size(); ++b)
      bank_ring_[b * ring_size_ + (k & ring_mask_)] = static_cast<float>(bank_[b].process_double(v));
    lp_ring_[k & ring_mask_] = static_cast<float>(y);
    const double beta = std::max(1.0 - std::exp(-dt_ / mean_tc_s_), 1.0 / static_cast<double>(n_));
    mean_ += beta * (y - mean_);
    if (n_ <= warmup_n_) return;
    if (spyloc_) spyloc_step(out);
    else montage_step(k, y, out);
  }

  // ------------------------------------------------------------------ montage

  void montage_step(std::uint64_t k, double y, EventSink& out) noexcept {
    const double h = 0.25 * thr_;
    switch (phase_) {
      case Phase::Unknown:
        if (y > mean_ + h) start_above(k, y);
        else if (y < mean_ - h) start_below(k, y);
        break;
      case Phase::Above:
        if (y > max_) {
          max_ = y;
          k_max_ = k;
        }
        if (y < mean_ - h) {
          have_peak_ = true;
          start_below(k, y);
        }
        break;
      case Phase::Below:
        if (y < min_) {
          min_ = y;
          k_min_ = k;
        }
        if (y > mean_ + h) {
          if (have_peak_) evaluate_montage(out);
          have_peak_ = false;
          start_above(k, y);
        }
        break;
    }
  }

  void start_above(std::uint64_t k, double y) noexcept {
    phase_ = Phase::Above;
    max_ = y;
    k_max_ = k;
  }
  void start_below(std::uint64_t k, double y) noexcept {
    phase_ = Phase::Below;
    min_ = y;
    k_min_ = k;
  }

  void evaluate_montage(EventSink& out) noexcept {
    const double amp = max_ - min_;
    if (amp < thr_) return;
    const double t_peak = grid_time(k_max_);
    if (have_last_ && t_peak - last_t_ < min_step_s_) return;
    const bool continuing = have_last_ && t_peak - last_t_ <= max_step_s_;
    if (!continuing) n_amp_ = n_int_ = 0;  // a new walk: nothing to compare with
    const bool weak = weak_peak(amp);
    if (continuing && weak && early_peak(t_peak)) {
      ++secondary_rejected_;
      return;
    }
    remember(amp, weak, t_peak);
    double f;
    if (have_last_ && t_peak - last_t_ <= max_step_s_) {
      f = 1.0 / (t_peak - last_t_);
    } else {
      const double half = static_cast<double>(k_min_ - k_max_) * dt_;
      f = half > 0 ? 0.5 / half : 1.0 / max_step_s_;
      f = std::clamp(f, 1.0 / max_step_s_, 1.0 / min_step_s_);
    }
    track_frequency(f);
    const std::size_t len = static_cast<std::size_t>(std::lround(rate_ / f));
    emit(t_peak, f, n_, len, out);
  }

  /// A weak, early peak is a bump between two steps, not a step: gait harmonics (the second harmonic
  /// of the step frequency plus a left/right asymmetry) put a bump mid-stride whose peak-valley can
  /// exceed the absolute threshold; a phone held at some angles sees it every other step (foreign
  /// montage-103's U1: 46 steps found for 30). Weak: below secondary_ratio x the largest of the last 3
  /// steps' peak-valley. Early: sooner after the last strong step than secondary_early x the median
  /// interval between strong steps (so a walk that started on a bump does not lock onto half
  /// periods). A weak peak at the expected time is a step (a walker who slows down bounces less).
  bool weak_peak(double amp) const noexcept {
    if (n_amp_ == 0 || secondary_ratio_ <= 0.0) return false;
    double ref = 0.0;
    for (std::size_t i = 0; i < std::min(n_amp_, kHist); ++i) ref = std::max(ref, amp_hist_[i]);
    return amp < secondary_ratio_ * ref;
  }
  bool early_peak(double t) const noexcept {
    const std::size_t m = std::min(n_int_, kHist);
    if (m < 2) return true;  // no cadence yet: weakness alone decides
    double iv[kHist];
    std::copy(int_hist_, int_hist_ + m, iv);
    std::sort(iv, iv + m);
    const double median = (m % 2 == 1) ? iv[m / 2] : 0.5 * (iv[m / 2 - 1] + iv[m / 2]);
    return t - last_strong_t_ < secondary_early_ * median;
  }
  void remember(double amp, bool weak, double t) noexcept {
    // A step this much stronger than the one before: the cadence so far was measured on bumps (a
    // walk that started on them while its bounce grew).
    if (n_amp_ > 0 && secondary_ratio_ > 0.0 && secondary_ratio_ * amp > amp_hist_[(n_amp_ - 1) % kHist]) n_int_ = 0;
    amp_hist_[n_amp_++ % kHist] = amp;
    if (weak) return;
    if (n_amp_ > 1 && t - last_strong_t_ <= max_step_s_) int_hist_[n_int_++ % kHist] = t - last_strong_t_;
    last_strong_t_ = t;
  }

  // ------------------------------------------------------------------ spyloc

  void spyloc_step(EventSink& out) noexcept {
    if (w_ < warmup_n_) w_ = warmup_n_;
    while (n_ >= w_ + m_max_) {
      for (std::size_t i = 0; i < m_max_; ++i) window_[i] = lp_ring_[(w_ + i) & ring_mask_];
      double m = 0, s = 0;
      for (float x : window_) m += x;
      m /= static_cast<double>(m_max_);
      for (float x : window_) s += (x - m) * (x - m);
      s = std::sqrt(s / static_cast<double>(m_max_));
      if (s < min_std_ || !zscore(window_.data(), m_max_)) {
        w_ += hop_;
        continue;
      }
      const dsp::DtwOpenEndMatch match = dtw_->open_end(template_, window_, m_min_, m_max_, dtw_window_);
      if (match.length == 0 || !(match.normalized_cost < dtw_threshold_)) {
        w_ += hop_;
        continue;
      }
      // The matched step itself must be walking and start on its peak (the z-scored window may
      // hold mostly standing still with a walk starting at its end).
      double sm = 0, ss = 0;
      for (std::size_t i = 0; i < match.length; ++i) sm += lp_ring_[(w_ + i) & ring_mask_];
      sm /= static_cast<double>(match.length);
      for (std::size_t i = 0; i < match.length; ++i) ss += std::pow(lp_ring_[(w_ + i) & ring_mask_] - sm, 2);
      ss = std::sqrt(ss / static_cast<double>(match.length));
      if (ss < min_std_ || lp_ring_[w_ & ring_mask_] - sm < 0.7 * ss) {
        w_ += hop_;
        continue;
      }
      const double t = grid_time(w_);
      if (have_last_ && t - last_t_ < min_step_s_) {
        w_ += hop_;
        continue;
      }
      const double f = (have_last_ && t - last_t_ <= max_step_s_) ? 1.0 / (t - last_t_)
                                                                    : rate_ / static_cast<double>(match.length);
      track_frequency(f);
      emit(t, f, w_ + match.length, match.length, out);
      // Next window: one step later, re-aligned on the largest sample near there (still unseen
      // samples are not searched).
      const std::uint64_t target = w_ + match.length;
      const std::uint64_t lo = std::max<std::uint64_t>(w_ + m_min_, target > dtw_window_ ? target - dtw_window_ : 0);
      const std::uint64_t hi = std::min<std::uint64_t>(target + dtw_window_, n_ - 1);
      std::uint64_t best = target;
      float best_v = -INFINITY;
      for (std::uint64_t j = lo; j <= hi; ++j)
        if (lp_ring_[j & ring_mask_] > best_v) {
          best_v = lp_ring_[j & ring_mask_];
          best = j;
        }
      w_ = std::max(best, w_ + 1);
    }
  }

  // ------------------------------------------------------------------ stride and emission

  /// Bounce over the `len` samples ending before grid index `end`, band-passed by the bank's band
  /// nearest the step frequency (its filter settled: it ran all along).
  double bounce_m(std::uint64_t end, std::size_t len) noexcept {
    len = std::min<std::size_t>({len, scratch_v_.size() - 1, static_cast<std::size_t>(std::min<std::uint64_t>(end, ring_size_))});
    if (len < 4) return kNaN;
    const std::uint64_t start = end - len;
    double v = 0.0, vmean = 0.0;
    for (std::size_t i = 0; i < len; ++i) {
      v += bank_ring_[active_ * ring_size_ + ((start + i) & ring_mask_)] * dt_;
      scratch_v_[i] = v;
      vmean += v;
    }
    vmean /= static_cast<double>(len);
    double pos = 0.0;
    for (std::size_t i = 0; i < len; ++i) {
      pos += (scratch_v_[i] - vmean) * dt_;
      scratch_p_[i] = pos;
    }
    const double p0 = scratch_p_[0], p1 = scratch_p_[len - 1];
    double lo = INFINITY, hi = -INFINITY;
    for (std::size_t i = 0; i < len; ++i) {
      const double d = scratch_p_[i] - (p0 + (p1 - p0) * static_cast<double>(i) / static_cast<double>(len - 1));
      lo = std::min(lo, d);
      hi = std::max(hi, d);
    }
    return hi - lo;
  }

  void emit(double t, double f, std::uint64_t seg_end, std::size_t seg_len, EventSink& out) noexcept {
    double stride = kNaN;
    if (bounce_) {
      const double h = std::min(bounce_m(seg_end, seg_len), leg_m_);
      if (std::isfinite(h)) stride = bounce_k_ * 2.0 * std::sqrt(std::max(0.0, 2.0 * leg_m_ * h - h * h));
    } else {
      stride = stride_a_ * f + stride_b_;
    }
    Step st;
    st.device = device_;
    st.detector = detector_;
    st.t_s = t;
    st.stride_m = static_cast<float>(stride);
    st.frequency_hz = static_cast<float>(f);
    if (!out.emit(Event{st})) ++dropped_;
    last_t_ = t;
    have_last_ = true;
  }

  Logger* log_ = nullptr;
  DeviceId device_;
  NameTag detector_;
  motion_common::AttitudeTracker tracker_;
  bool spyloc_ = false, bounce_ = true;
  double rate_ = 100.0, dt_ = 0.01;
  dsp::SosFilter lp_;
  std::vector<dsp::SosFilter> bank_;
  std::vector<double> centers_;
  std::size_t active_ = 0;
  double mean_tc_s_ = 3.0, min_step_s_ = 0.25, max_step_s_ = 1.0, thr_ = 1.0;
  double secondary_ratio_ = 0.45, secondary_early_ = 0.75;
  static constexpr std::size_t kHist = 3;
  double amp_hist_[kHist] = {}, int_hist_[kHist] = {}, last_strong_t_ = 0.0;
  std::size_t n_amp_ = 0, n_int_ = 0;
  std::uint64_t secondary_rejected_ = 0;
  double stride_a_ = 0.25, stride_b_ = 0.25, leg_m_ = 0.9, bounce_k_ = 1.0;
  std::uint64_t warmup_n_ = 0;
  std::size_t m_min_ = 25, m_max_ = 100, ring_size_ = 512, ring_mask_ = 511;
  std::vector<float> lp_ring_, bank_ring_;  ///< bank_ring_: every band's output, band-major
  std::vector<double> scratch_v_, scratch_p_;
  double dtw_threshold_ = 0.4;
  std::size_t dtw_window_ = 10, hop_ = 5;
  double min_std_ = 0.4;
  std::vector<float> template_, window_;
  std::unique_ptr<dsp::Dtw> dtw_;

  // Stream state.
  double prev_t_ = 0.0, prev_v_ = 0.0, grid_t0_ = 0.0;
  std::uint64_t n_ = 0;
  double mean_ = 0.0;
  Phase phase_ = Phase::Unknown;
  double max_ = 0.0, min_ = 0.0;
  std::uint64_t k_max_ = 0, k_min_ = 0;
  bool have_peak_ = false, have_last_ = false;
  double last_t_ = 0.0;
  std::uint64_t w_ = 0;
  std::uint64_t dropped_ = 0;
};

const ParamSchema* schema_fn() { return &schema(); }
Detector* create() { return new StepsDetector(); }

}  // namespace

const ParamSchema& schema() {
  static const ParamSchema schema = [] {
    using motion_common::append_ahrs_params;
    ParamSchema s;
    s.push_back(enum_param("mode", std::string("montage"), {"montage", "spyloc"},
                           "Step detector: Montage peak/valley crossing or SpyLoc adaptive-window DTW."));
    s.push_back(enum_param("stride_model", std::string("bounce"), {"bounce", "linear"},
                           "Stride length: Montage inverted-pendulum bounce or SpyLoc s = a*f + b."));
    s.push_back(float_param("grid_rate_hz", 100.0, 10.0, 1000.0, "Hz", "Rate of the regular grid the IMU is resampled onto."));
    s.push_back(float_param("lowpass_hz", 5.0, 0.5, 50.0, "Hz", "Low-pass cutoff on the vertical acceleration (Montage: 5 Hz)."));
    s.push_back(int_param("lowpass_order", std::int64_t{4}, 1, 12, "", "Butterworth order of that low-pass."));
    s.push_back(float_param("mean_time_constant_s", 3.0, 0.1, 600.0, "s", "Time constant of the running mean (the crossing level)."));
    s.push_back(float_param("min_step_s", 0.25, 0.1, 2.0, "s", "Shortest step (highest step frequency)."));
    s.push_back(float_param("max_step_s", 1.0, 0.2, 5.0, "s", "Longest step; a longer pause starts a new walk."));
    s.push_back(float_param("secondary_ratio", 0.45, 0.0, 1.0, "",
                            "Montage: a peak weaker than this x the largest of the last 3 steps' peak-valley and early "
                            "(secondary_early) is a gait-harmonic bump, not a step; 0 turns the check off."));
    s.push_back(float_param("secondary_early", 0.75, 0.1, 1.0, "",
                            "Montage: 'early' = less than this x the median of the last 3 step intervals after the last step."));
    s.push_back(float_param("min_peak_valley_mps2", 1.0, 0.01, 100.0, "m/s^2",
                            "Montage: smallest peak-to-valley swing of the low-passed vertical acceleration."));
    s.push_back(float_param("warmup_s", 0.5, 0.0, 60.0, "s", "No detection for this long after a (re)start (filters settle)."));
    ParamSpec tmpl;
    tmpl.key = "template";
    tmpl.type = ParamType::FloatList;
    tmpl.default_value = std::vector<double>{};
    tmpl.doc = "SpyLoc: step template (any length >= 4, resampled to template_s); empty = one cosine cycle from the peak.";
    s.push_back(tmpl);
    s.push_back(float_param("template_s", 0.55, 0.05, 5.0, "s", "SpyLoc: template duration on the grid."));
    s.push_back(float_param("dtw_threshold", 0.4, 0.0, 100.0, "",
                            "SpyLoc: a step when the DTW cost / (n + m) of z-scored signals is below this (paper: 0.4)."));
    s.push_back(float_param("dtw_window_s", 0.1, 0.0, 2.0, "s", "SpyLoc: DTW band half-width around the allowed warps."));
    s.push_back(float_param("search_hop_s", 0.05, 0.005, 2.0, "s", "SpyLoc: window shift when no step is found."));
    s.push_back(float_param("min_accel_std_mps2", 0.4, 0.0, 100.0, "m/s^2",
                            "SpyLoc: windows with a lower standard deviation are not walking."));
    s.push_back(float_param("stride_a", 0.25, -5.0, 5.0, "m*s", "Linear stride model slope a (s = a*f + b)."));
    s.push_back(float_param("stride_b", 0.25, -5.0, 5.0, "m", "Linear stride model intercept b."));
    s.push_back(float_param("leg_length_m", 0.9, 0.3, 1.5, "m", "Bounce model: leg length (pendulum radius)."));
    s.push_back(float_param("bounce_k", 1.0, 0.1, 5.0, "", "Bounce model: per-person correction factor (Montage's k)."));
    s.push_back(int_param("bandpass_order", std::int64_t{2}, 1, 6, "", "Order of the walking-frequency band-pass prototypes."));
    append_ahrs_params(s, 0.5);
    return s;
  }();
  return schema;
}

const locus_plugin_descriptor* descriptor() {
  static const locus_plugin_descriptor d{
      LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_DETECTOR, "steps", "0.1.0",
      "walking steps and stride length from the IMU (Montage peak/valley or SpyLoc DTW)", kInputImu, &schema_fn,
      &create, nullptr,
  };
  return &d;
}

}  // namespace locus::plugins::steps
