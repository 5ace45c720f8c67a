// The room's acoustics (renderer.hpp): tables in the constructor, the real-time render in process().
#include "locus/room/renderer.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace locus::room {

namespace {

double bessel_i0(double x) {
  double sum = 1.0, term = 1.0;
  for (int k = 1; k < 50; ++k) {
    term *= (x / (2.0 * k)) * (x / (2.0 * k));
    sum += term;
    if (term < 1e-12 * sum) break;
  }
  return sum;
}

// The interpolator is also the converters' anti-aliasing low-pass: a windowed sinc at kCutoff·fs/2
// (19.4 kHz at 44.1 kHz, −6 dB) whose every phase has the same response up to the band edge. Why: a
// half-sample delay of content near fs/2 is unavoidably attenuated (an even symmetric FIR has a zero at
// fs/2), so a full-band interpolator filters an arrival differently for every fractional delay, which
// the chirp detector's carrier-cycle choice notices (measured: confidence 0.01-0.9 and cycle slips with
// a full-band 32- or 64-tap design, 1.00 and no bias with this one, on the AMIL 18-22 kHz beep). A real
// DAC and ADC band-limit the same way (passbands end near 0.45·fs), the same for every arrival.
constexpr double kKaiserBeta = 10.0;
constexpr double kCutoff = 0.88;
constexpr double kOnsetGap_s = 0.1;

}  // namespace

Eigen::Vector3d RoomRenderer::Track::at(double tau, double t0, double step) const noexcept {
  if (p.size() == 1) return p[0];
  double u = (tau - t0) / step;
  if (!(u > 0.0)) return p.front();  // also -inf (layout not started) and NaN
  const double last = static_cast<double>(p.size() - 1);
  if (u >= last) return p.back();
  const auto i = static_cast<std::size_t>(u);
  const double f = u - static_cast<double>(i);
  return p[i] + f * (p[i + 1] - p[i]);
}

RoomRenderer::RoomRenderer(const Layout& layout, RendererConfig cfg)
    : fs_(layout.sample_rate_hz), c_(layout.speed_of_sound_mps), cfg_(std::move(cfg)) {
  if (!(fs_ > 0.0) || !(c_ > 0.0)) throw std::invalid_argument("room: the layout needs a positive sample rate and speed of sound");
  if (layout.devices.empty()) throw std::invalid_argument("room: the layout has no devices");
  if (cfg_.reflection_order < 0 || cfg_.reflection_order > 1)
    throw std::invalid_argument("room: reflections: expected order 0 (direct only) or 1 (first-order images), got " +
                                std::to_string(cfg_.reflection_order));
  if (cfg_.reflection_order > 0 && !cfg_.room_size_m)
    throw std::invalid_argument("room: reflections need a room (the layout's environment.room, or --room X,Y,Z)");
  if (!(cfg_.reflection >= 0.0 && cfg_.reflection <= 1.0))
    throw std::invalid_argument("room: the reflection coefficient must be in [0, 1]");
  if (!cfg_.skew_ppm.empty() && cfg_.skew_ppm.size() != layout.devices.size())
    throw std::invalid_argument("room: one skew per device expected");
  if (cfg_.max_block_frames == 0 || cfg_.max_block_frames > (1u << 20)) throw std::invalid_argument("room: max_block_frames out of range");
  if (!(cfg_.self_gain >= 0.0)) throw std::invalid_argument("room: self_gain must be >= 0");
  if (!(cfg_.level_at_1m > 0.0) || !(cfg_.min_distance_m > 0.0) || !(cfg_.noise_rms >= 0.0) || !(cfg_.max_duration_s > 0.0))
    throw std::invalid_argument("room: level_at_1m, min_distance_m and max_duration_s must be > 0, noise_rms >= 0");

  // Position tables over the layout's time range.
  t0_ = layout.t_begin_s;
  step_ = cfg_.table_step_s;
  const double span = std::max(0.0, layout.t_end_s - layout.t_begin_s);
  const auto steps = static_cast<std::size_t>(std::ceil(span / step_)) + 1;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = Eigen::Vector3d::Constant(-1e300);
  auto track = [&](const LayoutDevice& d, const Eigen::Vector3d& body) {
    Track t;
    const std::size_t n = d.trajectory->is_static() ? 1 : steps;
    t.p.reserve(n);
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d w = d.trajectory->pose(t0_ + static_cast<double>(i) * step_).to_world(body);
      lo = lo.cwiseMin(w);
      hi = hi.cwiseMax(w);
      t.p.push_back(w);
    }
    return t;
  };
  double min_offset_s = 0.0;
  for (std::size_t i = 0; i < layout.devices.size(); ++i) {
    const LayoutDevice& ld = layout.devices[i];
    Device d;
    d.speaker = track(ld, ld.speaker_or_origin_m());
    for (const auto& m : ld.mics_body_m) d.mics.push_back(track(ld, m));
    d.mic_offset = total_mics_;
    total_mics_ += d.mics.size();
    d.skew_ppm = cfg_.skew_ppm.empty() ? 0.0 : cfg_.skew_ppm[i];
    if (!(std::abs(d.skew_ppm) <= 1000.0))
      throw std::invalid_argument("room: device '" + ld.id + "': skew " + std::to_string(d.skew_ppm) + " ppm: expected within ±1000 ppm");
    d.rate = 1.0 / (1.0 + d.skew_ppm * 1e-6);
    // Half the interpolator plus a margin keeps every tap in the past; a slow clock (rate > 1) samples
    // later and later true times: start it far enough back to stay causal for max_duration_s.
    d.offset_s = -(kTaps / 2 + 2) / fs_ - (d.rate > 1.0 ? (d.rate - 1.0) * cfg_.max_duration_s : 0.0);
    min_offset_s = std::min(min_offset_s, d.offset_s);
    devices_.push_back(std::move(d));
  }
  // The longest path: across the room and back (first-order image), or across the layout's extent.
  double reach_m = (hi - lo).norm() + 1.0;
  if (cfg_.room_size_m) reach_m = std::max(reach_m, 2.0 * cfg_.room_size_m->norm() + 1.0);
  max_delay_s_ = reach_m / c_ - min_offset_s;
  reach_frames_ = static_cast<std::uint64_t>(std::ceil(max_delay_s_ * fs_)) + kTaps + kControl;
  std::uint64_t len = 1;
  while (len < reach_frames_ + cfg_.max_block_frames + 2 * kTaps) len <<= 1;
  history_len_ = len;
  history_mask_ = len - 1;
  history_.assign(devices_.size() * history_len_, 0.0f);
  last_loud_.assign(devices_.size(), 0);
  silent_run_.assign(devices_.size(), std::numeric_limits<std::uint32_t>::max());

  // Paths: every speaker into every microphone (its own too: the self-recording), direct and images.
  const int images = cfg_.reflection_order > 0 ? 6 : 0;
  for (std::uint32_t s = 0; s < devices_.size(); ++s)
    for (std::uint32_t r = 0; r < devices_.size(); ++r)
      for (std::uint32_t m = 0; m < devices_[r].mics.size(); ++m)
        for (int im = -1; im < images; ++im)
          paths_.push_back(Path{s, r, m, im,
                                static_cast<float>(im >= 0 ? cfg_.reflection : s == r ? cfg_.self_gain : 1.0)});

  // The interpolator: row ph holds the weights of history samples i0 − (kTaps/2 − 1) .. i0 + kTaps/2
  // for a read position i0 + ph / kPhases (Kaiser-windowed sinc, unit DC gain).
  table_.assign(static_cast<std::size_t>(kPhases + 1) * kTaps, 0.0f);
  const double i0b = bessel_i0(kKaiserBeta);
  for (int ph = 0; ph <= kPhases; ++ph) {
    const double frac = static_cast<double>(ph) / kPhases;
    double sum = 0.0;
    double w[kTaps];
    for (int t = 0; t < kTaps; ++t) {
      const double x = frac + (kTaps / 2 - 1) - t;  // distance from the read position to sample t
      const double sinc = std::abs(x) < 1e-12 ? kCutoff : std::sin(M_PI * kCutoff * x) / (M_PI * x);
      const double r = x / (kTaps / 2.0);
      const double win = std::abs(r) >= 1.0 ? 0.0 : bessel_i0(kKaiserBeta * std::sqrt(1.0 - r * r)) / i0b;
      w[t] = sinc * win;
      sum += w[t];
    }
    for (int t = 0; t < kTaps; ++t) table_[static_cast<std::size_t>(ph) * kTaps + t] = static_cast<float>(w[t] / sum);
  }

  // Noise: uniform in [-a, a] has RMS a/sqrt(3).
  noise_amp_ = static_cast<float>(cfg_.noise_rms * std::sqrt(3.0));
  std::uint64_t x = cfg_.seed * 0x9E3779B97F4A7C15ull + 1;
  for (std::size_t i = 0; i < total_mics_; ++i) {
    x ^= x >> 33;
    x *= 0xff51afd7ed558ccdull;
    x ^= x >> 33;
    noise_.push_back(Noise{static_cast<std::uint32_t>(x) | 1u});
  }
  const std::size_t ctrl = cfg_.max_block_frames / kControl + 2;
  ctrl_src_.assign(ctrl, 0.0);
  ctrl_gain_.assign(ctrl, 0.0);
}

void RoomRenderer::start_layout_at(double t_room_s) noexcept {
  double expected = std::numeric_limits<double>::infinity();
  layout_start_s_.compare_exchange_strong(expected, t_room_s, std::memory_order_acq_rel);
}

Eigen::Vector3d RoomRenderer::image_of(const Eigen::Vector3d& p, int image) const noexcept {
  if (image < 0) return p;
  Eigen::Vector3d q = p;
  const int axis = image / 2;
  q[axis] = (image % 2 == 0) ? -p[axis] : 2.0 * (*cfg_.room_size_m)[axis] - p[axis];
  return q;
}

void RoomRenderer::geometry(const Path& path, double k, double start, double& src_index, double& gain) const noexcept {
  const Device& rx = devices_[path.rx];
  const Device& src = devices_[path.src];
  const double t_rx = rx.rate * (k / fs_) + rx.offset_s;  // the true time this output sample hears
  const Eigen::Vector3d pm = rx.mics[path.mic].at(t_rx - start, t0_, step_);
  double te = t_rx;
  double r = 0.0;
  for (int it = 0; it < 3; ++it) {
    r = (pm - image_of(src.speaker.at(te - start, t0_, step_), path.image)).norm();
    te = t_rx - r / c_;
  }
  src_index = te * fs_;
  gain = static_cast<double>(path.gain) * cfg_.level_at_1m / std::max(r, cfg_.min_distance_m);
}

void RoomRenderer::process(const float* const* speakers, float* const* mics, std::uint32_t n) noexcept {
  if (n > cfg_.max_block_frames) n = cfg_.max_block_frames;  // refused config; never overrun a buffer
  const std::uint64_t first = frames_.load(std::memory_order_relaxed);
  // 1. Speakers into their histories; silence, loudness and onsets.
  for (std::size_t s = 0; s < devices_.size(); ++s) {
    float* hist = history_.data() + s * history_len_;
    const float* in = speakers != nullptr ? speakers[s] : nullptr;
    for (std::uint32_t j = 0; j < n; ++j) {
      const float v = in != nullptr ? in[j] : 0.0f;
      hist[(first + j) & history_mask_] = v;
      if (std::abs(v) > 1e-6f) {
        if (silent_run_[s] >= static_cast<std::uint64_t>(kOnsetGap_s * fs_)) {
          const std::uint64_t w = onset_write_.load(std::memory_order_relaxed);
          if (w - onset_read_.load(std::memory_order_acquire) < kOnsetCapacity) {
            onsets_[w % kOnsetCapacity] = Onset{static_cast<std::uint32_t>(s), first + j};
            onset_write_.store(w + 1, std::memory_order_release);
          } else {
            onsets_dropped_.fetch_add(1, std::memory_order_relaxed);
          }
        }
        silent_run_[s] = 0;
        last_loud_[s] = first + j + 1;
      } else if (silent_run_[s] < std::numeric_limits<std::uint32_t>::max()) {
        ++silent_run_[s];
      }
    }
  }
  // 2. Noise.
  for (std::size_t i = 0; i < total_mics_; ++i) {
    float* out = mics[i];
    std::uint32_t x = noise_[i].state;
    for (std::uint32_t j = 0; j < n; ++j) {
      x ^= x << 13;
      x ^= x >> 17;
      x ^= x << 5;
      out[j] = noise_amp_ * (static_cast<float>(x) * (2.0f / 4294967296.0f) - 1.0f);
    }
    noise_[i].state = x;
  }
  // 3. Paths whose speaker sounded within reach.
  const double start = layout_start_s_.load(std::memory_order_acquire);
  const std::uint32_t nctrl = (n + kControl - 1) / kControl;
  std::uint64_t rendered = 0;
  for (const Path& p : paths_) {
    // silent for longer than the longest path at this block's first frame: nothing of it is in the air
    if (last_loud_[p.src] == 0 || first > last_loud_[p.src] + reach_frames_) continue;
    ++rendered;
    for (std::uint32_t c = 0; c <= nctrl; ++c) {
      const double k = static_cast<double>(first) + static_cast<double>(std::min<std::uint32_t>(c * kControl, n));
      geometry(p, k, start, ctrl_src_[c], ctrl_gain_[c]);
    }
    const float* hist = history_.data() + p.src * history_len_;
    float* out = mics[devices_[p.rx].mic_offset + p.mic];
    const std::int64_t newest = static_cast<std::int64_t>(first + n) - 1;
    const std::int64_t oldest = static_cast<std::int64_t>(first + n) - static_cast<std::int64_t>(history_len_) + kTaps;
    for (std::uint32_t c = 0; c < nctrl; ++c) {
      const std::uint32_t j0 = c * kControl, j1 = std::min<std::uint32_t>(j0 + kControl, n);
      const double s0 = ctrl_src_[c], g0 = ctrl_gain_[c];
      const double ds = (ctrl_src_[c + 1] - s0) / static_cast<double>(j1 - j0);
      const double dg = (ctrl_gain_[c + 1] - g0) / static_cast<double>(j1 - j0);
      for (std::uint32_t j = j0; j < j1; ++j) {
        const double pos = s0 + ds * static_cast<double>(j - j0);
        const double fl = std::floor(pos);
        auto i0 = static_cast<std::int64_t>(fl);
        int ph = static_cast<int>((pos - fl) * kPhases + 0.5);
        const std::int64_t lo = i0 - (kTaps / 2 - 1), hi = i0 + kTaps / 2;
        if (hi > newest || lo < oldest || lo < 0) continue;  // not heard yet / long gone / before the start
        const float* h = table_.data() + static_cast<std::size_t>(ph) * kTaps;
        float acc = 0.0f;
        for (int t = 0; t < kTaps; ++t) acc += hist[static_cast<std::uint64_t>(lo + t) & history_mask_] * h[t];
        out[j] += static_cast<float>(g0 + dg * static_cast<double>(j - j0)) * acc;
      }
    }
  }
  // 4. Microphones clip at full scale.
  std::uint64_t clipped = 0;
  for (std::size_t i = 0; i < total_mics_; ++i) {
    float* out = mics[i];
    for (std::uint32_t j = 0; j < n; ++j) {
      if (out[j] > 1.0f) {
        out[j] = 1.0f;
        ++clipped;
      } else if (out[j] < -1.0f) {
        out[j] = -1.0f;
        ++clipped;
      }
    }
  }
  if (clipped) clipped_.fetch_add(clipped, std::memory_order_relaxed);
  if (rendered) path_blocks_.fetch_add(rendered, std::memory_order_relaxed);
  frames_.store(first + n, std::memory_order_release);
}

void RoomRenderer::skip(std::uint64_t n) noexcept {
  if (n == 0) return;
  const std::uint64_t first = frames_.load(std::memory_order_relaxed);
  const std::uint64_t zero = std::min<std::uint64_t>(n, history_len_);
  for (std::size_t s = 0; s < devices_.size(); ++s) {
    float* hist = history_.data() + s * history_len_;
    for (std::uint64_t j = n - zero; j < n; ++j) hist[(first + j) & history_mask_] = 0.0f;
    silent_run_[s] = std::min<std::uint64_t>(silent_run_[s] + n, std::numeric_limits<std::uint32_t>::max());
  }
  frames_.store(first + n, std::memory_order_release);
}

bool RoomRenderer::pop_onset(Onset& out) noexcept {
  const std::uint64_t r = onset_read_.load(std::memory_order_relaxed);
  if (r == onset_write_.load(std::memory_order_acquire)) return false;
  out = onsets_[r % kOnsetCapacity];
  onset_read_.store(r + 1, std::memory_order_release);
  return true;
}

double RoomRenderer::direct_arrival_s(std::size_t src, double te_s, std::size_t rx, std::size_t mic) const noexcept {
  const double start = layout_start_s();
  const Eigen::Vector3d ps = devices_[src].speaker.at(te_s - start, t0_, step_);
  double t = te_s;
  for (int it = 0; it < 4; ++it) t = te_s + (devices_[rx].mics[mic].at(t - start, t0_, step_) - ps).norm() / c_;
  return t;
}

double RoomRenderer::distance_m(std::size_t src, std::size_t rx, std::size_t mic, double t_s) const noexcept {
  const double start = layout_start_s();
  return (devices_[rx].mics[mic].at(t_s - start, t0_, step_) - devices_[src].speaker.at(t_s - start, t0_, step_)).norm();
}

}  // namespace locus::room
