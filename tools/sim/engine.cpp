// The simulator engine (engine.hpp): validation, acoustic rendering with per-sample propagation
// delays and image sources, noise, device responses, sensor streams, truth and scene.yaml.
//
// Rendering is organised per receiving device in blocks: every (emission, device) "contribution"
// covers a short frame range around its arrivals (plus the speaker filter's ring-down); it is rendered
// into its own buffer, filtered by the source's speaker response, and added into an accumulator that
// spans one block plus the longest contribution. Between emissions only noise is generated, so a
// minute of 4-device audio renders in seconds.
#include "locus/sim/engine.hpp"

#include <algorithm>
#include <fstream>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <regex>
#include <set>
#include <stdexcept>

#include <yaml-cpp/yaml.h>

#include "locus/dsp/iir.hpp"
#include "locus/sim/interference.hpp"
#include "locus/sim/response.hpp"

namespace locus::sim {

namespace fs = std::filesystem;

namespace {

constexpr std::size_t kBlockFrames = 1 << 16;
constexpr double kFilterTail_s = 0.02;  // speaker filter ring-down kept after the last arrival

void fail(const std::string& what) { throw std::invalid_argument("simulation: " + what); }

std::string fmt(double v) { return scene::format_double(v); }

// One image source of a shoebox room: p_img = sign ⊙ p + offset, amplitude factor gain.
struct Image {
  Eigen::Vector3d sign{1, 1, 1};
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  double gain = 1.0;
  int order = 0;
  Eigen::Vector3d apply(const Eigen::Vector3d& p) const { return sign.cwiseProduct(p) + offset; }
};

std::vector<Image> enumerate_images(const AcousticModel& a) {
  std::vector<Image> out;
  out.push_back(Image{});  // direct path first
  if (!a.room || a.room->max_order <= 0) return out;
  const Room& room = *a.room;
  const int n_max = room.max_order;
  struct AxisImage {
    double sign, offset, gain;
    int order;
  };
  std::array<std::vector<AxisImage>, 3> axes;
  for (int ax = 0; ax < 3; ++ax) {
    const double L = room.size_m[ax];
    const double beta_low = room.reflection[static_cast<std::size_t>(2 * ax)];
    const double beta_high = room.reflection[static_cast<std::size_t>(2 * ax + 1)];
    for (int n = -n_max; n <= n_max; ++n) {
      for (int q = 0; q <= 1; ++q) {
        const int hits_low = std::abs(n - q), hits_high = std::abs(n);
        const int order = hits_low + hits_high;
        if (order > n_max) continue;
        axes[static_cast<std::size_t>(ax)].push_back(
            {q ? -1.0 : 1.0, 2.0 * n * L, std::pow(beta_low, hits_low) * std::pow(beta_high, hits_high), order});
      }
    }
  }
  for (const auto& x : axes[0])
    for (const auto& y : axes[1])
      for (const auto& z : axes[2]) {
        const int order = x.order + y.order + z.order;
        if (order == 0 || order > n_max) continue;
        Image im;
        im.sign = {x.sign, y.sign, z.sign};
        im.offset = {x.offset, y.offset, z.offset};
        im.gain = x.gain * y.gain * z.gain;
        im.order = order;
        out.push_back(im);
      }
  // Deterministic order: by reflection order, then by offset/sign (enumeration order is already fixed).
  std::stable_sort(out.begin(), out.end(), [](const Image& a, const Image& b) { return a.order < b.order; });
  return out;
}

// A sound source as the renderer sees it (device speaker or emitter).
struct Source {
  std::string id;
  const std::vector<dsp::SignalSpec>* emits = nullptr;
  const Trajectory* trajectory = nullptr;
  Eigen::Vector3d speaker_body = Eigen::Vector3d::Zero();
  double level = 1.0;
  BandLimit response;
  // The emitting device's DAC runs on its own clock: the sound is the signal at its local time since
  // the start, (t − te0)·(1 + skew_ppm·1e-6) (1 for emitters without a clock). A device that hears
  // itself then records its own emission on one clock, unstretched, as a real phone does.
  double dac_rate = 1.0;
};

std::vector<dsp::Biquad> design(const BandLimit& b, double fs) { return design_response(b, fs); }  // response.hpp

// Pink noise: Paul Kellet's refined filter of white noise, scaled to unit RMS.
class PinkFilter {
 public:
  double next(double w) noexcept {
    b_[0] = 0.99886 * b_[0] + w * 0.0555179;
    b_[1] = 0.99332 * b_[1] + w * 0.0750759;
    b_[2] = 0.96900 * b_[2] + w * 0.1538520;
    b_[3] = 0.86650 * b_[3] + w * 0.3104856;
    b_[4] = 0.55000 * b_[4] + w * 0.5329522;
    b_[5] = -0.7616 * b_[5] - w * 0.0168980;
    const double out = b_[0] + b_[1] + b_[2] + b_[3] + b_[4] + b_[5] + b_[6] + w * 0.5362;
    b_[6] = w * 0.115926;
    return out * kScale;
  }

 private:
  // 1 / RMS of the filter output for unit white input (sqrt of the sum of squared impulse response).
  static inline const double kScale = [] {
    double b[7] = {0, 0, 0, 0, 0, 0, 0};
    double energy = 0.0;
    for (int n = 0; n < 200000; ++n) {
      const double w = n == 0 ? 1.0 : 0.0;
      b[0] = 0.99886 * b[0] + w * 0.0555179;
      b[1] = 0.99332 * b[1] + w * 0.0750759;
      b[2] = 0.96900 * b[2] + w * 0.1538520;
      b[3] = 0.86650 * b[3] + w * 0.3104856;
      b[4] = 0.55000 * b[4] + w * 0.5329522;
      b[5] = -0.7616 * b[5] - w * 0.0168980;
      const double out = b[0] + b[1] + b[2] + b[3] + b[4] + b[5] + b[6] + w * 0.5362;
      b[6] = w * 0.115926;
      energy += out * out;
    }
    return 1.0 / std::sqrt(energy);
  }();
  double b_[7] = {0, 0, 0, 0, 0, 0, 0};
};

struct Burst {
  std::uint64_t k0, k1;        // frame range
  std::vector<double> wave;    // babble / music waveform (unit RMS, k1 − k0 samples); empty = white
};

// Centre frequency of an acoustic signal (air absorption): lfm mid-band, multitone mean, gold carrier.
double centre_frequency_hz(const dsp::SignalSpec& s) {
  if (s.type == "lfm") return 0.5 * (s.f0_hz + s.f1_hz);
  if (s.type == "multitone" && !s.tones_hz.empty()) {
    double m = 0.0;
    for (double f : s.tones_hz) m += f;
    return m / static_cast<double>(s.tones_hz.size());
  }
  if (s.type == "gold") return s.carrier_hz;
  return 0.0;
}

// Everything needed to render one receiving device.
class DeviceRenderer {
 public:
  DeviceRenderer(const Simulation& sim, const DeviceModel& dev, const std::vector<Source>& sources,
                 const std::vector<Image>& images, std::uint64_t frames)
      : sim_(sim), dev_(dev), sources_(sources), images_(images), frames_(frames),
        channels_(dev.mics_body_m.size()), fs_(sim.sample_rate_hz), c_(sim.acoustics.speed_of_sound_mps) {
    evaluators_.resize(sources_.size());
    for (std::size_t i = 0; i < sources_.size(); ++i)
      for (const auto& spec : *sources_[i].emits)
        evaluators_[i].push_back(spec.acoustic() ? std::make_unique<dsp::SignalEvaluator>(spec, fs_) : nullptr);
    plan();
  }

  /// Renders every frame, block by block, into sink(interleaved, frames).
  template <class Sink>
  void run(Sink&& sink, WriteReport& report) {
    const std::size_t acc_len = kBlockFrames + max_len_ + 1;
    std::vector<std::vector<double>> acc(channels_, std::vector<double>(acc_len, 0.0));
    std::vector<float> inter(kBlockFrames * channels_);
    std::vector<std::vector<double>> contrib(channels_);
    // filters and noise generators
    std::vector<dsp::SosFilter> mic_filters;
    const bool band = sim_.acoustics.band_limits && dev_.mic_response.enabled();
    for (std::size_t ch = 0; ch < channels_; ++ch) mic_filters.emplace_back(design(dev_.mic_response, fs_));
    std::vector<Rng> noise_rng, self_rng;
    std::vector<PinkFilter> pink(channels_);
    for (std::size_t ch = 0; ch < channels_; ++ch) {
      noise_rng.push_back(Rng::derive(sim_.seed, "noise/" + dev_.id + "/" + std::to_string(ch)));
      self_rng.push_back(Rng::derive(sim_.seed, "selfnoise/" + dev_.id + "/" + std::to_string(ch)));
    }
    const NoiseModel& nm = sim_.acoustics.noise;
    const double sigma = nm.enabled ? sim_.acoustics.level_at_1m / std::sqrt(2.0) / std::pow(10.0, nm.snr_db / 20.0) : 0.0;
    const double w_white = std::sqrt(1.0 - std::clamp(nm.pink_fraction, 0.0, 1.0));
    const double w_pink = std::sqrt(std::clamp(nm.pink_fraction, 0.0, 1.0));
    const double burst_gain = std::pow(10.0, nm.burst_db / 20.0);
    const double self_sigma = nm.enabled && nm.self_noise_snr_db
                                  ? sim_.acoustics.level_at_1m / std::sqrt(2.0) / std::pow(10.0, *nm.self_noise_snr_db / 20.0)
                                  : 0.0;

    std::size_t next_contrib = 0;
    std::size_t next_burst = 0;
    for (std::uint64_t start = 0; start < frames_; start += kBlockFrames) {
      const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(kBlockFrames, frames_ - start));
      // contributions starting in this block
      while (next_contrib < plans_.size() && plans_[next_contrib].base < start + n) {
        const Plan& p = plans_[next_contrib++];
        render_contribution(p, contrib, report);
        const std::size_t off = static_cast<std::size_t>(p.base - start);
        for (std::size_t ch = 0; ch < channels_; ++ch)
          for (std::size_t i = 0; i < contrib[ch].size(); ++i) acc[ch][off + i] += contrib[ch][i];
        ++report.contributions;
      }
      // noise (acoustic: before the mic response)
      if (sigma > 0.0) {
        for (std::size_t ch = 0; ch < channels_; ++ch) {
          Rng& rng = noise_rng[ch];
          auto& a = acc[ch];
          for (std::size_t i = 0; i < n; ++i) {
            const double w = rng.normal();
            double v = w_white * w;
            if (w_pink > 0.0) v += w_pink * pink[ch].next(rng.normal());
            a[i] += sigma * v;
          }
        }
        // bursts overlapping this block
        while (next_burst < bursts_.size() && bursts_[next_burst].k1 <= start) ++next_burst;
        for (std::size_t b = next_burst; b < bursts_.size() && bursts_[b].k0 < start + n; ++b) {
          const Burst& br = bursts_[b];
          const std::uint64_t k0 = std::max(br.k0, start), k1 = std::min(br.k1, start + n);
          const double len = static_cast<double>(br.k1 - br.k0);
          if (!br.wave.empty()) {  // babble / music: the same sound on every channel
            for (std::size_t ch = 0; ch < channels_; ++ch)
              for (std::uint64_t k = k0; k < k1; ++k)
                acc[ch][static_cast<std::size_t>(k - start)] +=
                    sigma * burst_gain * br.wave[static_cast<std::size_t>(k - br.k0)];
            continue;
          }
          for (std::size_t ch = 0; ch < channels_; ++ch) {
            Rng& rng = noise_rng[ch];
            for (std::uint64_t k = k0; k < k1; ++k) {
              const double u = static_cast<double>(k - br.k0) / len;
              const double env = std::sin(M_PI * u);  // smooth rise and fall
              acc[ch][static_cast<std::size_t>(k - start)] += sigma * burst_gain * env * rng.normal();
            }
          }
        }
      }
      // mic response, gain, clipping, interleave
      for (std::size_t ch = 0; ch < channels_; ++ch) {
        auto& a = acc[ch];
        for (std::size_t i = 0; i < n; ++i) {
          double v = band ? mic_filters[ch].process_double(a[i]) : a[i];
          if (self_sigma > 0.0) v += self_sigma * self_rng[ch].normal();  // mic self-noise (electrical)
          v *= dev_.mic_gain;
          if (v > 1.0) {
            v = 1.0;
            ++report.clipped_samples;
          } else if (v < -1.0) {
            v = -1.0;
            ++report.clipped_samples;
          }
          inter[i * channels_ + ch] = static_cast<float>(v);
        }
        // shift the accumulator by one block
        std::copy(a.begin() + static_cast<std::ptrdiff_t>(n), a.end(), a.begin());
        std::fill(a.end() - static_cast<std::ptrdiff_t>(n), a.end(), 0.0);
      }
      sink(inter.data(), n);
    }
  }


 private:
  struct Plan {
    std::size_t emission;
    std::uint64_t base, end;  // frame range [base, end)
  };
  struct PathWindow {
    std::size_t mic, image;
    std::int64_t k0, k1;  // inclusive
  };

  double true_from_local_frame(double k) const { return dev_.clock.true_from_local(k / fs_); }

  Eigen::Vector3d mic_world(std::size_t mic, double t) const {
    return dev_.trajectory->pose(t).to_world(dev_.mics_body_m[mic]);
  }
  Eigen::Vector3d spk_world(const Source& s, const Image& im, double te) const {
    return im.apply(s.trajectory->pose(te).to_world(s.speaker_body));
  }
  // Arrival time at the mic of a sound leaving the (image) speaker at te.
  double arrival(const Source& s, const Image& im, std::size_t mic, double te) const {
    const Eigen::Vector3d ps = spk_world(s, im, te);
    double t = te + (mic_world(mic, te) - ps).norm() / c_;
    for (int i = 0; i < 50; ++i) {
      const double tn = te + (mic_world(mic, t) - ps).norm() / c_;
      if (std::abs(tn - t) < 1e-13) return tn;
      t = tn;
    }
    return t;
  }

  void path_windows(const Emission& e, const Source& s, std::vector<PathWindow>& out) const {
    out.clear();
    const double te0 = e.t_start_true_s();
    // the evaluator's support: [0, duration) for closed forms, a few samples wider for interpolated ones
    const dsp::SignalEvaluator& ev = *evaluators_[source_index(e.source_id)][static_cast<std::size_t>(e.signal_index)];
    for (std::size_t m = 0; m < channels_; ++m) {
      for (std::size_t p = 0; p < images_.size(); ++p) {
        const double extra_s = p == 0 ? obstruction_extra_m(e) / c_ : 0.0;
        const double ta = arrival(s, images_[p], m, te0 + ev.begin_s()) + extra_s;
        const double tb = arrival(s, images_[p], m, te0 + ev.end_s()) + extra_s;
        const double la = dev_.clock.local_from_true(std::min(ta, tb)) * fs_;
        const double lb = dev_.clock.local_from_true(std::max(ta, tb)) * fs_;
        PathWindow w{m, p, static_cast<std::int64_t>(std::floor(la)) - 2, static_cast<std::int64_t>(std::ceil(lb)) + 2};
        w.k0 = std::max<std::int64_t>(w.k0, 0);
        w.k1 = std::min<std::int64_t>(w.k1, static_cast<std::int64_t>(frames_) - 1);
        if (w.k0 <= w.k1) out.push_back(w);
      }
    }
  }

  std::size_t source_index(const std::string& id) const {
    for (std::size_t i = 0; i < sources_.size(); ++i)
      if (sources_[i].id == id) return i;
    return 0;  // validated before
  }

  void plan() {
    std::int64_t tail = (sim_.acoustics.band_limits ? static_cast<std::int64_t>(std::ceil(kFilterTail_s * fs_)) : 0);
    const auto& room = sim_.acoustics.room;
    if (room && room->diffuse_tail) {
      // the longest tail of any signal (lowest centre frequency: least air absorption)
      double worst = 0.0;
      for (const auto& src : sources_)
        for (const auto& spec : *src.emits)
          if (spec.acoustic()) worst = std::max(worst, diffuse_tail_params(centre_frequency_hz(spec)).end_s);
      tail += static_cast<std::int64_t>(std::ceil(worst * fs_)) + 1;
    }
    std::vector<PathWindow> w;
    for (std::size_t ei = 0; ei < sim_.emissions.size(); ++ei) {
      const Emission& e = sim_.emissions[ei];
      const Source& s = sources_[source_index(e.source_id)];
      path_windows(e, s, w);
      if (w.empty()) continue;
      std::int64_t k0 = w.front().k0, k1 = w.front().k1;
      for (const auto& x : w) {
        k0 = std::min(k0, x.k0);
        k1 = std::max(k1, x.k1);
      }
      k1 = std::min<std::int64_t>(k1 + tail, static_cast<std::int64_t>(frames_) - 1);
      plans_.push_back(Plan{ei, static_cast<std::uint64_t>(k0), static_cast<std::uint64_t>(k1) + 1});
      max_len_ = std::max<std::size_t>(max_len_, static_cast<std::size_t>(k1 - k0 + 1));
    }
    std::stable_sort(plans_.begin(), plans_.end(), [](const Plan& a, const Plan& b) { return a.base < b.base; });
    // noise bursts: Poisson process over the recording
    const NoiseModel& nm = sim_.acoustics.noise;
    if (nm.enabled && nm.bursts_per_minute > 0.0) {
      Rng rng = Rng::derive(sim_.seed, "bursts/" + dev_.id);
      Rng wave_rng = Rng::derive(sim_.seed, "burstwave/" + dev_.id);
      const double mean_gap = 60.0 / nm.bursts_per_minute;
      double t = rng.exponential(mean_gap);
      const double total = static_cast<double>(frames_) / fs_;
      while (t < total) {
        const double d = rng.uniform(nm.burst_min_s, nm.burst_max_s);
        const auto k0 = static_cast<std::uint64_t>(t * fs_);
        const auto k1 = std::min<std::uint64_t>(frames_, static_cast<std::uint64_t>((t + d) * fs_) + 1);
        if (k1 > k0 + 1) {
          Burst b{k0, k1, {}};
          using K = NoiseModel::BurstKind;
          if (nm.burst_kind != K::White) {
            const bool babble = nm.burst_kind == K::Babble || (nm.burst_kind == K::Mixed && wave_rng.bernoulli(0.5));
            b.wave = synth_interference(babble ? InterferenceKind::Babble : InterferenceKind::Music,
                                        static_cast<std::size_t>(k1 - k0), fs_, wave_rng);
          }
          bursts_.push_back(std::move(b));
        }
        t += d + rng.exponential(mean_gap);
      }
    }
  }

  struct TailParams {
    double start_s = 0.0, tau_s = 0.0, end_s = 0.0, energy = 0.0;  // energy relative to the direct sound at 1 m
  };
  // Sabine diffuse tail of the room at frequency fc (Room::diffuse_tail).
  TailParams diffuse_tail_params(double fc) const {
    TailParams p;
    const Room& room = *sim_.acoustics.room;
    const Eigen::Vector3d& L = room.size_m;
    const double V = L.prod(), S = 2.0 * (L.x() * L.y() + L.y() * L.z() + L.x() * L.z());
    double mean_b2 = 0.0;
    for (double b : room.reflection) mean_b2 += b * b / 6.0;
    const double alpha = std::clamp(1.0 - mean_b2, 1e-3, 1.0);
    const double m = sim_.acoustics.air_absorption && fc > 0.0
                         ? air_absorption_db_per_m(fc, sim_.acoustics.temperature_c, sim_.acoustics.humidity_pct) / 4.343
                         : 0.0;  // intensity attenuation per metre
    const double A = S * alpha + 4.0 * m * V;
    const double rt60 = 0.161 * V / A;
    p.tau_s = rt60 / 6.91;  // amplitude e-folding time
    p.start_s = std::max(1, room.max_order) * L.minCoeff() / c_;
    p.end_s = p.start_s + 5.0 * p.tau_s;
    p.energy = 16.0 * M_PI / A * std::exp(-2.0 * p.start_s / p.tau_s);
    return p;
  }

  // Adds the diffuse tail of the direct path to buf (all mics, independent tails per mic).
  void add_diffuse_tail(const Plan& plan, const Emission& e, const Source& s, std::vector<std::vector<double>>& buf) {
    const Room& room = *sim_.acoustics.room;
    const auto& spec = (*s.emits)[static_cast<std::size_t>(e.signal_index)];
    const TailParams tp = diffuse_tail_params(centre_frequency_hz(spec));
    if (!(tp.energy > 0.0) || room.tail_taps <= 0) return;
    Rng rng = Rng::derive(sim_.seed, "tail/" + dev_.id + "/" + std::to_string(plan.emission));
    const double g_1m = sim_.acoustics.level_at_1m * s.level * e.gain;
    const dsp::SignalEvaluator& ev = *evaluators_[source_index(e.source_id)][static_cast<std::size_t>(e.signal_index)];
    // the dry signal as it leaves the speaker, on this device's sample grid, from the direct arrival
    const double t_dir = arrival(s, images_.front(), 0, e.t_start_true_s());
    const double k_dir = dev_.clock.local_from_true(t_dir) * fs_ - static_cast<double>(plan.base);
    const std::size_t len = buf.front().size();
    const auto sig_len = static_cast<std::size_t>(std::ceil(ev.end_s() * fs_)) + 2;
    std::vector<double> dry(sig_len);
    const double frac = k_dir - std::floor(k_dir);
    for (std::size_t i = 0; i < sig_len; ++i) dry[i] = ev.value((static_cast<double>(i) - frac) / fs_);
    const auto k0 = static_cast<std::int64_t>(std::floor(k_dir));
    // Reflection times grow denser as t² (a room's echo density 4π c³ t² / V); one tap per reflection
    // up to tail_taps, each reflection's amplitude ~ e^(−t/τ)/(c t) (spherical spreading), and no tap
    // louder than one path of its length can be: the image sources cover max_order reflections, so a
    // tail path has at least max_order + 1 (β_max^(max_order+1) e^(−κ c t) / (c t)).
    const Eigen::Vector3d& L = room.size_m;
    const double t_a = t_dir - e.t_start_true_s() + tp.start_s, t_b = t_dir - e.t_start_true_s() + tp.end_s;
    const double physical = 4.0 * M_PI * c_ * c_ * c_ * (t_b * t_b * t_b - t_a * t_a * t_a) / (3.0 * L.prod());
    const auto n_taps = static_cast<std::size_t>(std::clamp(physical, 1.0, static_cast<double>(room.tail_taps)));
    const double beta_max = *std::max_element(room.reflection.begin(), room.reflection.end());
    const double beta_tail = std::pow(beta_max, std::max(1, room.max_order) + 1);
    const double kappa = sim_.acoustics.air_absorption && centre_frequency_hz(spec) > 0.0
                             ? air_absorption_db_per_m(centre_frequency_hz(spec), sim_.acoustics.temperature_c,
                                                       sim_.acoustics.humidity_pct) * std::log(10.0) / 20.0
                             : 0.0;
    // a tap stands for physical / n_taps reflections when the count is capped (incoherent sum)
    const double per_tap = std::sqrt(std::max(1.0, physical / static_cast<double>(n_taps)));
    std::vector<double> taps(n_taps), bound(n_taps);
    std::vector<std::int64_t> delays(taps.size());
    for (std::size_t ch = 0; ch < channels_; ++ch) {
      double e2 = 0.0;
      for (std::size_t j = 0; j < taps.size(); ++j) {
        const double u = rng.uniform();
        const double t = std::cbrt(t_a * t_a * t_a + u * (t_b * t_b * t_b - t_a * t_a * t_a));  // since emission
        const double d = t - (t_dir - e.t_start_true_s());                                      // after the direct path
        delays[j] = static_cast<std::int64_t>(std::llround(d * fs_));
        taps[j] = rng.normal() * std::exp(-(d - tp.start_s) / tp.tau_s) / (c_ * t);
        bound[j] = per_tap * beta_tail * std::exp(-kappa * c_ * t) / (c_ * t);
        e2 += taps[j] * taps[j];
      }
      const double scale = e2 > 0.0 ? std::sqrt(tp.energy / e2) : 0.0;
      for (std::size_t j = 0; j < taps.size(); ++j) taps[j] = g_1m * std::clamp(scale * taps[j], -bound[j], bound[j]);
      auto& out = buf[ch];
      for (std::size_t j = 0; j < taps.size(); ++j) {
        const double a = taps[j];
        const std::int64_t at = k0 + delays[j];
        for (std::size_t i = 0; i < sig_len; ++i) {
          const std::int64_t k = at + static_cast<std::int64_t>(i);
          if (k >= 0 && k < static_cast<std::int64_t>(len)) out[static_cast<std::size_t>(k)] += a * dry[i];
        }
      }
    }
  }

  double obstruction_extra_m(const Emission& e) const {
    double x = 0.0;
    const double te0 = e.t_start_true_s();
    for (const auto& o : sim_.acoustics.obstructions) {
      const bool pair = (o.a == e.source_id && o.b == dev_.id) || (o.b == e.source_id && o.a == dev_.id);
      if (pair && te0 >= o.t_begin_s && te0 < o.t_end_s) x += o.extra_path_m;
    }
    return x;
  }

  // Gain of the obstructions on path `image` from speaker position spk (the real one) to mic position
  // mic: the direct path (image 0) takes every obstruction of the pair; a reflected path only those
  // with a wall_m segment that its route in the room crosses (obstructed_route).
  double obstruction_gain(const Emission& e, std::size_t image, const Eigen::Vector3d& spk,
                          const Eigen::Vector3d& mic) const {
    double g = 1.0;
    const double te0 = e.t_start_true_s();
    for (const auto& o : sim_.acoustics.obstructions) {
      const bool pair = (o.a == e.source_id && o.b == dev_.id) || (o.b == e.source_id && o.a == dev_.id);
      if (!pair || te0 < o.t_begin_s || te0 >= o.t_end_s) continue;
      if (image != 0 && (!o.wall_m || !sim_.acoustics.room ||
                         !obstructed_route(images_[image].apply(spk), mic, *o.wall_m, sim_.acoustics.room->size_m)))
        continue;
      g *= std::pow(10.0, -o.attenuation_db / 20.0);
    }
    return g;
  }

  // Whether the horizontal route of a reflected path crosses a wall segment: the straight line from
  // the image source to the mic (the unfolded path) is sampled and folded back into the room
  // [0, Lx] x [0, Ly] (a mirror per wall crossed); consecutive folded points form the route's pieces.
  static bool obstructed_route(const Eigen::Vector3d& image_src, const Eigen::Vector3d& mic,
                               const std::array<Eigen::Vector2d, 2>& wall, const Eigen::Vector3d& room) {
    auto fold = [](double u, double L) {
      double r = std::fmod(u, 2.0 * L);
      if (r < 0.0) r += 2.0 * L;
      return r > L ? 2.0 * L - r : r;
    };
    auto cross2 = [](const Eigen::Vector2d& u, const Eigen::Vector2d& v) { return u.x() * v.y() - u.y() * v.x(); };
    auto crosses = [&](const Eigen::Vector2d& p, const Eigen::Vector2d& q) {
      const Eigen::Vector2d &a = wall[0], &b = wall[1];
      const double d1 = cross2(q - p, a - p), d2 = cross2(q - p, b - p);
      const double d3 = cross2(b - a, p - a), d4 = cross2(b - a, q - a);
      return ((d1 > 0) != (d2 > 0)) && ((d3 > 0) != (d4 > 0));
    };
    const Eigen::Vector2d s = image_src.head<2>(), m = mic.head<2>();
    const int n = std::max(8, static_cast<int>(std::ceil((m - s).norm() / 0.05)));  // 5 cm pieces
    Eigen::Vector2d prev(fold(s.x(), room.x()), fold(s.y(), room.y()));
    for (int i = 1; i <= n; ++i) {
      const Eigen::Vector2d u = s + (m - s) * (static_cast<double>(i) / n);
      const Eigen::Vector2d cur(fold(u.x(), room.x()), fold(u.y(), room.y()));
      if (crosses(prev, cur)) return true;
      prev = cur;
    }
    return false;
  }

  void render_contribution(const Plan& plan, std::vector<std::vector<double>>& buf, WriteReport& report) {
    const Emission& e = sim_.emissions[plan.emission];
    const std::size_t si = source_index(e.source_id);
    const Source& s = sources_[si];
    const dsp::SignalEvaluator& ev = *evaluators_[si][static_cast<std::size_t>(e.signal_index)];
    const std::size_t len = static_cast<std::size_t>(plan.end - plan.base);
    for (auto& b : buf) b.assign(len, 0.0);
    std::vector<PathWindow> windows;
    path_windows(e, s, windows);
    const double te0 = e.t_start_true_s();
    const double base_gain = sim_.acoustics.level_at_1m * s.level * e.gain;
    // air absorption at the signal's centre frequency: gain exp(−kappa·r)
    const double fc = centre_frequency_hz((*s.emits)[static_cast<std::size_t>(e.signal_index)]);
    const double kappa = sim_.acoustics.air_absorption && fc > 0.0
                             ? air_absorption_db_per_m(fc, sim_.acoustics.temperature_c, sim_.acoustics.humidity_pct) *
                                   std::log(10.0) / 20.0
                             : 0.0;
    const double obstruct_extra_m = obstruction_extra_m(e);
    const double rmin = sim_.acoustics.min_distance_m;
    const bool rx_static = dev_.trajectory->is_static();
    const bool src_static = s.trajectory->is_static();
    // Per-frame true times and (moving receiver) mic positions are shared by every path; a moving
    // speaker is sampled on a 0.1 ms grid around the emission and interpolated linearly (error
    // a·h²/8: 2e-8 m at 15 m/s², far below a 1e-3-sample delay error).
    t_of_.resize(len);
    for (std::size_t i = 0; i < len; ++i) t_of_[i] = true_from_local_frame(static_cast<double>(plan.base + i));
    if (!rx_static) {
      mic_cache_.resize(channels_);
      for (std::size_t m = 0; m < channels_; ++m) {
        mic_cache_[m].resize(len);
        for (std::size_t i = 0; i < len; ++i) mic_cache_[m][i] = mic_world(m, t_of_[i]);
      }
    }
    constexpr double kGridStep_s = 1e-4, kGridPad_s = 0.005;
    const double grid_t0 = te0 + ev.begin_s() - kGridPad_s;
    if (!src_static) {
      const auto n = static_cast<std::size_t>(std::ceil((ev.end_s() - ev.begin_s() + 2 * kGridPad_s) / kGridStep_s)) + 2;
      spk_grid_.resize(n);
      for (std::size_t j = 0; j < n; ++j)
        spk_grid_[j] = s.trajectory->pose(grid_t0 + static_cast<double>(j) * kGridStep_s).to_world(s.speaker_body);
    }
    auto spk_at = [&](const Image& im, double te) -> Eigen::Vector3d {
      double u = (te - grid_t0) / kGridStep_s;
      u = std::clamp(u, 0.0, static_cast<double>(spk_grid_.size() - 2));
      const auto j = static_cast<std::size_t>(u);
      const double f = u - static_cast<double>(j);
      return im.apply(spk_grid_[j] + f * (spk_grid_[j + 1] - spk_grid_[j]));
    };
    for (const PathWindow& w : windows) {
      ++report.paths;
      const Image& im = images_[w.image];
      const double self = e.source_id == dev_.id ? dev_.self_gain : 1.0;
      auto& out = buf[w.mic];
      const Eigen::Vector3d mic_static = rx_static ? mic_world(w.mic, 0.0) : Eigen::Vector3d::Zero();
      // obstructions: the geometry at the window's middle (a path is blocked or not for a whole beep)
      const double t_mid = t_of_[static_cast<std::size_t>((w.k0 + w.k1) / 2 - static_cast<std::int64_t>(plan.base))];
      const double obstruct = obstruction_gain(e, w.image, s.trajectory->pose(te0).to_world(s.speaker_body),
                                               rx_static ? mic_static : mic_world(w.mic, t_mid));
      const double g = base_gain * im.gain * obstruct * (w.image == 0 ? self : 1.0);
      const Eigen::Vector3d spk_static = src_static ? spk_world(s, im, 0.0) : Eigen::Vector3d::Zero();
      double delay = -1.0;  // warm start for moving sources
      for (std::int64_t k = w.k0; k <= w.k1; ++k) {
        const auto i = static_cast<std::size_t>(k - static_cast<std::int64_t>(plan.base));
        const double t = t_of_[i];
        const Eigen::Vector3d& pm = rx_static ? mic_static : mic_cache_[w.mic][i];
        double r;
        if (src_static) {
          r = (pm - spk_static).norm();
        } else {
          // solve t − te = |pm − p_spk(te)| / c by fixed-point iteration (contraction factor v/c)
          if (delay < 0.0) delay = (pm - spk_at(im, t)).norm() / c_;
          double te = t - delay;
          for (int it = 0; it < 20; ++it) {
            r = (pm - spk_at(im, te)).norm();
            const double te_new = t - r / c_;
            const double diff = std::abs(te_new - te);
            te = te_new;
            if (diff < 1e-14) break;
          }
          delay = t - te;
          r = delay * c_;
        }
        if (w.image == 0) r += obstruct_extra_m;  // diffracted first path: longer
        const double te = t - r / c_;
        const double v = ev.value((te - te0) * s.dac_rate);
        if (v != 0.0) out[i] += g / std::max(r, rmin) * v * (kappa > 0.0 ? std::exp(-kappa * r) : 1.0);
      }
    }
    if (sim_.acoustics.room && sim_.acoustics.room->diffuse_tail) add_diffuse_tail(plan, e, s, buf);
    if (sim_.acoustics.band_limits && s.response.enabled()) {
      dsp::SosFilter f(design(s.response, fs_));
      for (auto& b : buf) {
        f.reset();
        for (auto& x : b) x = f.process_double(x);
      }
    }
  }

  const Simulation& sim_;
  const DeviceModel& dev_;
  const std::vector<Source>& sources_;
  const std::vector<Image>& images_;
  std::uint64_t frames_;
  std::size_t channels_;
  double fs_, c_;
  std::vector<std::vector<std::unique_ptr<dsp::SignalEvaluator>>> evaluators_;
  std::vector<Plan> plans_;
  std::vector<Burst> bursts_;
  std::size_t max_len_ = 0;
  // scratch of render_contribution (kept to avoid reallocations)
  std::vector<double> t_of_;
  std::vector<std::vector<Eigen::Vector3d>> mic_cache_;
  std::vector<Eigen::Vector3d> spk_grid_;
};

std::vector<Source> collect_sources(const Simulation& sim) {
  std::vector<Source> out;
  for (const auto& d : sim.devices) {
    if (!d.speaker_body_m || d.emits.empty()) continue;
    out.push_back(Source{d.id, &d.emits, d.trajectory.get(), *d.speaker_body_m, d.source_level, d.speaker_response,
                         1.0 + d.clock.skew_ppm * 1e-6});
  }
  for (const auto& e : sim.emitters) {
    if (e.emits.empty()) continue;
    out.push_back(Source{e.id, &e.emits, e.trajectory.get(), Eigen::Vector3d::Zero(), e.source_level, e.speaker_response});
  }
  return out;
}

scene::Vec3 to_vec3(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

scene::TruthRow truth_row(double t, const std::string& id, const Pose& p) {
  scene::TruthRow r;
  r.t_s = t;
  r.id = id;
  r.position_m = to_vec3(p.position_m);
  Eigen::Quaterniond q = p.attitude.normalized();
  if (q.w() < 0) q.coeffs() = -q.coeffs();
  r.q_wxyz = {q.w(), q.x(), q.y(), q.z()};
  return r;
}

}  // namespace

// ------------------------------------------------------------------------------------------ KinematicImu

ImuReading KinematicImu::sample(const Simulation& sim, const DeviceModel& device, double t, Rng& rng) {
  if (!biased_) {
    for (int i = 0; i < 3; ++i) {
      accel_bias_[i] = rng.normal(0.0, cfg_.accel_bias_mps2);
      gyro_bias_[i] = rng.normal(0.0, cfg_.gyro_bias_radps);
    }
    biased_ = true;
  }
  const Trajectory& tr = *device.trajectory;
  const Pose p = tr.pose(t);
  const Eigen::Quaterniond world_to_body = p.attitude.conjugate();
  ImuReading r;
  const Eigen::Vector3d specific = tr.acceleration(t) + Eigen::Vector3d(0, 0, cfg_.gravity_mps2);
  r.accel_mps2 = world_to_body * specific + accel_bias_;
  r.gyro_radps = tr.angular_velocity_body(t) + gyro_bias_;
  for (int i = 0; i < 3; ++i) {
    r.accel_mps2[i] += rng.normal(0.0, cfg_.accel_noise_mps2);
    r.gyro_radps[i] += rng.normal(0.0, cfg_.gyro_noise_radps);
  }
  if (cfg_.magnetometer && sim.magnetic_field_world_ut) {
    Eigen::Vector3d m = world_to_body * *sim.magnetic_field_world_ut;
    for (int i = 0; i < 3; ++i) m[i] += rng.normal(0.0, cfg_.mag_noise_ut);
    r.mag_ut = m;
  }
  return r;
}

// ------------------------------------------------------------------------------------------ air absorption

double air_absorption_db_per_m(double f, double temperature_c, double humidity_pct) {
  // ISO 9613-1:1993, eqs. (3)-(5) and annex B (saturation vapour pressure), p_a = p_r = 101.325 kPa.
  const double T = temperature_c + 273.15, T0 = 293.15, T01 = 273.16;
  const double psat_rel = std::pow(10.0, -6.8346 * std::pow(T01 / T, 1.261) + 4.6151);
  const double h = humidity_pct * psat_rel;  // molar concentration of water vapour, %
  const double frO = 24.0 + 4.04e4 * h * (0.02 + h) / (0.391 + h);
  const double frN = std::pow(T / T0, -0.5) * (9.0 + 280.0 * h * std::exp(-4.170 * (std::pow(T / T0, -1.0 / 3.0) - 1.0)));
  const double f2 = f * f;
  return 8.686 * f2 *
         (1.84e-11 * std::sqrt(T / T0) +
          std::pow(T / T0, -2.5) * (0.01275 * std::exp(-2239.1 / T) / (frO + f2 / frO) +
                                    0.1068 * std::exp(-3352.0 / T) / (frN + f2 / frN)));
}

// ------------------------------------------------------------------------------------------ Simulation

const DeviceModel* Simulation::find_device(const std::string& id) const {
  for (const auto& d : devices)
    if (d.id == id) return &d;
  return nullptr;
}
const EmitterModel* Simulation::find_emitter(const std::string& id) const {
  for (const auto& e : emitters)
    if (e.id == id) return &e;
  return nullptr;
}

Eigen::Vector3d speaker_position(const Simulation& sim, const std::string& id, double t) {
  if (const DeviceModel* d = sim.find_device(id)) {
    return d->trajectory->pose(t).to_world(d->speaker_body_m.value_or(Eigen::Vector3d::Zero()));
  }
  if (const EmitterModel* e = sim.find_emitter(id)) return e->trajectory->pose(t).position_m;
  throw std::invalid_argument("speaker_position: unknown source '" + id + "'");
}

// ------------------------------------------------------------------------------------------ SceneSimulator

SceneSimulator::SceneSimulator(Simulation sim) : sim_(std::move(sim)) {
  const std::regex id_re("[A-Za-z0-9_-]+");
  if (!(sim_.sample_rate_hz > 0.0) || sim_.sample_rate_hz != std::floor(sim_.sample_rate_hz))
    fail("sample_rate_hz must be a positive integer (got " + fmt(sim_.sample_rate_hz) + ")");
  if (!(sim_.duration_s > 0.0) || !std::isfinite(sim_.duration_s)) fail("duration_s must be > 0");
  if (!(sim_.acoustics.speed_of_sound_mps > 100.0 && sim_.acoustics.speed_of_sound_mps < 1000.0))
    fail("acoustics.speed_of_sound_mps must be in (100, 1000) m/s");
  if (!(sim_.truth_rate_hz > 0.0)) fail("truth_rate_hz must be > 0");
  std::set<std::string> ids;
  auto check_id = [&](const std::string& id, const char* what) {
    if (!std::regex_match(id, id_re)) fail(std::string(what) + " id '" + id + "' must match [A-Za-z0-9_-]+");
    if (!ids.insert(id).second) fail(std::string(what) + " id '" + id + "' is used twice");
  };
  for (const auto& d : sim_.devices) {
    check_id(d.id, "device");
    if (!d.trajectory) fail("device '" + d.id + "' has no trajectory");
    if (d.record_audio && d.mics_body_m.empty()) fail("device '" + d.id + "' records audio but has no mics");
    if (!d.emits.empty() && !d.speaker_body_m) fail("device '" + d.id + "' emits but has no speaker");
    if (std::abs(d.clock.skew_ppm) > 1000.0) fail("device '" + d.id + "': |skew_ppm| must be <= 1000");
    if (d.imu && !(d.imu->rate_hz() > 0.0)) fail("device '" + d.id + "': IMU rate must be > 0");
  }
  for (const auto& e : sim_.emitters) {
    check_id(e.id, "emitter");
    if (!e.trajectory) fail("emitter '" + e.id + "' has no trajectory");
  }
  for (std::size_t i = 0; i < sim_.emissions.size(); ++i) {
    const Emission& e = sim_.emissions[i];
    const std::vector<dsp::SignalSpec>* emits = nullptr;
    if (const auto* d = sim_.find_device(e.source_id)) emits = &d->emits;
    if (const auto* m = sim_.find_emitter(e.source_id)) emits = &m->emits;
    const std::string where = "emission " + std::to_string(i) + " (source '" + e.source_id + "')";
    if (!emits) fail(where + ": unknown source");
    if (e.signal_index < 0 || static_cast<std::size_t>(e.signal_index) >= emits->size())
      fail(where + ": signal_index " + std::to_string(e.signal_index) + " out of range (source has " +
           std::to_string(emits->size()) + " signals)");
    const auto& spec = (*emits)[static_cast<std::size_t>(e.signal_index)];
    if (!spec.acoustic()) fail(where + ": signal type '" + spec.type + "' is not acoustic");
    try {
      dsp::SignalEvaluator ev(spec, sim_.sample_rate_hz);
      (void)ev;
    } catch (const std::exception& ex) {
      fail(where + ": " + ex.what());
    }
    if (!std::isfinite(e.t_command_true_s) || !(e.latency_s >= 0.0)) fail(where + ": bad time or latency");
  }
  if (sim_.acoustics.room) {
    const Room& r = *sim_.acoustics.room;
    if (!(r.size_m.minCoeff() > 0.0)) fail("room size must be > 0 on every axis");
    if (r.max_order < 0 || r.max_order > 6) fail("room max_order must be 0..6");
    for (double b : r.reflection)
      if (!(b >= 0.0 && b <= 1.0)) fail("room reflection coefficients must be in [0, 1]");
    auto inside = [&](const Eigen::Vector3d& p) {
      return (p.array() >= 0.0).all() && (p.array() <= r.size_m.array()).all();
    };
    for (const auto& d : sim_.devices)
      for (double t : {0.0, 0.5 * sim_.duration_s, sim_.duration_s})
        if (!inside(d.trajectory->pose(t).position_m))
          fail("device '" + d.id + "' is outside the room at t=" + fmt(t) + " s");
    for (const auto& e : sim_.emitters)
      if (!inside(e.trajectory->pose(0.0).position_m)) fail("emitter '" + e.id + "' is outside the room at t=0");
  }
}

std::uint64_t SceneSimulator::audio_frames(const DeviceModel& d) const {
  const double local_end = d.clock.local_from_true(sim_.duration_s);
  return local_end <= 0.0 ? 0 : static_cast<std::uint64_t>(std::ceil(local_end * sim_.sample_rate_hz));
}

double SceneSimulator::direct_arrival_true_s(const std::string& source_id, double te, const std::string& rx,
                                             std::size_t mic) const {
  const DeviceModel* d = sim_.find_device(rx);
  if (!d || mic >= d->mics_body_m.size()) throw std::invalid_argument("direct_arrival_true_s: bad receiver/mic");
  const Eigen::Vector3d ps = speaker_position(sim_, source_id, te);
  const double c = sim_.acoustics.speed_of_sound_mps;
  double t = te + (d->trajectory->pose(te).to_world(d->mics_body_m[mic]) - ps).norm() / c;
  for (int i = 0; i < 50; ++i) t = te + (d->trajectory->pose(t).to_world(d->mics_body_m[mic]) - ps).norm() / c;
  return t;
}

std::vector<std::vector<float>> SceneSimulator::render_audio(const std::string& device_id, std::uint64_t first,
                                                             std::size_t frames) const {
  const DeviceModel* d = sim_.find_device(device_id);
  if (!d || d->mics_body_m.empty()) throw std::invalid_argument("render_audio: no audio device '" + device_id + "'");
  const auto sources = collect_sources(sim_);
  const auto images = enumerate_images(sim_.acoustics);
  const std::uint64_t total = audio_frames(*d);
  const std::size_t ch = d->mics_body_m.size();
  std::vector<std::vector<float>> out(ch);
  DeviceRenderer r(sim_, *d, sources, images, std::min<std::uint64_t>(total, first + frames));
  std::uint64_t pos = 0;
  WriteReport rep;
  r.run(
      [&](const float* inter, std::size_t n) {
        for (std::size_t i = 0; i < n; ++i, ++pos)
          if (pos >= first && pos < first + frames)
            for (std::size_t c = 0; c < ch; ++c) out[c].push_back(inter[i * ch + c]);
      },
      rep);
  return out;
}

namespace {

/// The scene's `environment` mapping, in flow style: the room size, the family, the seed, the
/// emission schedule file, then the family's own entries (Simulation::environment_yaml, the text of a
/// flow mapping's entries). Built with yaml-cpp, so write_scene_yaml() reads back what is written.
std::string environment_yaml(const Simulation& sim) {
  YAML::Node env(YAML::NodeType::Map);
  env.SetStyle(YAML::EmitterStyle::Flow);
  if (sim.acoustics.room) {
    const auto& r = *sim.acoustics.room;
    YAML::Node size(YAML::NodeType::Sequence);
    for (int i = 0; i < 3; ++i) size.push_back(fmt(r.size_m[i]));
    env["room"] = size;
  }
  if (!sim.family.empty()) env["family"] = sim.family;
  env["simulator_seed"] = std::to_string(sim.seed);
  env["truth_emissions"] = "truth_emissions.csv";
  if (!sim.environment_yaml.empty()) {
    YAML::Node extra;
    try {
      extra = YAML::Load("{" + sim.environment_yaml + "}");
    } catch (const YAML::Exception& e) {
      throw std::invalid_argument("environment_yaml: not the entries of a YAML mapping (" + std::string(e.what()) +
                                  "): " + sim.environment_yaml);
    }
    for (const auto& entry : extra) env[entry.first.Scalar()] = entry.second;
  }
  YAML::Emitter out;
  out << env;
  if (!out.good()) throw std::invalid_argument("environment_yaml: " + out.GetLastError());
  return out.c_str();
}

}  // namespace

WriteReport SceneSimulator::write(const std::string& out_dir) const {
  const auto t_begin = std::chrono::steady_clock::now();
  WriteReport rep;
  rep.dir = out_dir;
  fs::create_directories(out_dir);
  const auto sources = collect_sources(sim_);
  const auto images = enumerate_images(sim_.acoustics);
  const double fs_hz = sim_.sample_rate_hz;

  scene::Scene sc;
  sc.dir = out_dir;
  sc.name = sim_.name;
  sc.sample_rate_hz = fs_hz;
  sc.speed_of_sound_mps = sim_.acoustics.speed_of_sound_mps;
  sc.environment_yaml = environment_yaml(sim_);
  scene::Truth truth;
  truth.trajectories = "truth.csv";
  if (sim_.magnetic_field_world_ut) truth.magnetic_field_world_ut = to_vec3(*sim_.magnetic_field_world_ut);

  for (const auto& d : sim_.devices) {
    scene::DeviceSpec spec;
    spec.id = d.id;
    for (const auto& m : d.mics_body_m) spec.mics_m.push_back(to_vec3(m));
    if (d.speaker_body_m) spec.speaker_m = to_vec3(*d.speaker_body_m);
    spec.emits = d.emits;
    if (d.anchor_position_m) spec.anchor_position_m = to_vec3(*d.anchor_position_m);
    truth.clocks[d.id] = d.clock;
    const bool any_stream = (d.record_audio && !d.mics_body_m.empty()) || d.imu || d.ble || d.record_sync;
    if (any_stream) fs::create_directories(fs::path(out_dir) / d.id);
    const double local_end = d.clock.local_from_true(sim_.duration_s);

    if (d.record_audio && !d.mics_body_m.empty()) {
      spec.audio = d.id + "/audio.wav";
      scene::WavWriter wav((fs::path(out_dir) / spec.audio).string(), static_cast<int>(d.mics_body_m.size()), fs_hz,
                           sim_.audio_format);
      DeviceRenderer r(sim_, d, sources, images, audio_frames(d));
      r.run([&](const float* inter, std::size_t n) { wav.write(inter, n); }, rep);
      wav.close();
      rep.audio_frames_total += wav.frames_written();
    }
    if (d.imu) {
      spec.imu = d.id + "/imu.csv";
      scene::ImuCsvWriter w((fs::path(out_dir) / spec.imu).string(), d.imu->has_magnetometer());
      Rng rng = Rng::derive(sim_.seed, "imu/" + d.id);
      const double rate = d.imu->rate_hz();
      for (std::uint64_t k = 0;; ++k) {
        const double local = static_cast<double>(k) / rate;
        if (local >= local_end) break;
        const ImuReading r = d.imu->sample(sim_, d, d.clock.true_from_local(local), rng);
        ImuSample s;
        s.device = DeviceId(d.id);
        s.t_s = std::max(0.0, local + r.stamp_offset_s);  // row-stamp jitter (ImuReading::stamp_offset_s)
        for (int i = 0; i < 3; ++i) {
          s.accel_mps2[static_cast<std::size_t>(i)] = static_cast<float>(r.accel_mps2[i]);
          s.gyro_radps[static_cast<std::size_t>(i)] = static_cast<float>(r.gyro_radps[i]);
        }
        if (r.mag_ut) {
          s.has_mag = true;
          for (int i = 0; i < 3; ++i) s.mag_ut[static_cast<std::size_t>(i)] = static_cast<float>((*r.mag_ut)[i]);
        }
        w.write(s);
      }
      w.close();
    }
    if (d.ble) {
      spec.ble = d.id + "/ble.csv";
      std::vector<BleReception> rx;
      Rng rng = Rng::derive(sim_.seed, "ble/" + d.id);
      d.ble->scan(sim_, d, d.clock.true_from_local(0.0), sim_.duration_s, rng,
                  [&](const BleReception& r) { rx.push_back(r); });
      std::stable_sort(rx.begin(), rx.end(), [](const auto& a, const auto& b) { return a.t_true_s < b.t_true_s; });
      scene::BleCsvWriter w((fs::path(out_dir) / spec.ble).string());
      for (const auto& r : rx) {
        const double local = d.clock.local_from_true(r.t_true_s);
        if (local < 0.0 || local >= local_end) continue;
        BleAdvertisement a;
        a.device = DeviceId(d.id);
        a.t_s = local;
        a.address = r.address;
        a.rssi_dbm = static_cast<float>(r.rssi_dbm);
        if (r.tx_power_dbm) {
          a.has_tx_power = true;
          a.tx_power_dbm = static_cast<float>(*r.tx_power_dbm);
        }
        a.channel = static_cast<std::uint8_t>(r.channel);
        w.write(a);
      }
      w.close();
    }
    if (d.record_sync) {
      spec.sync = d.id + "/sync.csv";
      Rng rng = Rng::derive(sim_.seed, "sync/" + d.id);
      std::vector<std::pair<double, std::string>> rows;
      std::vector<const Emission*> ordered;
      for (const auto& e : sim_.emissions) ordered.push_back(&e);
      std::stable_sort(ordered.begin(), ordered.end(),
                       [](const Emission* a, const Emission* b) { return a->t_start_true_s() < b->t_start_true_s(); });
      for (const Emission* e : ordered) {
        const std::vector<dsp::SignalSpec>* emits = nullptr;
        if (const auto* sd = sim_.find_device(e->source_id)) emits = &sd->emits;
        if (const auto* se = sim_.find_emitter(e->source_id)) emits = &se->emits;
        const auto& spec_e = (*emits)[static_cast<std::size_t>(e->signal_index)];
        if (!spec_e.sync_delay_s) continue;
        const double t_send = e->t_start_true_s() - *spec_e.sync_delay_s;
        const double t_rx = t_send + sim_.radio_latency_s + rng.uniform(-sim_.radio_jitter_s, sim_.radio_jitter_s);
        if (sim_.radio_loss_probability > 0.0 && rng.uniform(0.0, 1.0) < sim_.radio_loss_probability) continue;
        const double local = d.clock.local_from_true(t_rx);
        if (local >= 0.0 && local < local_end) rows.emplace_back(local, e->source_id);
      }
      for (const auto& [t_send, src] : sim_.radio_broadcasts) {
        const double t_rx = t_send + sim_.radio_latency_s + rng.uniform(-sim_.radio_jitter_s, sim_.radio_jitter_s);
        if (sim_.radio_loss_probability > 0.0 && rng.uniform(0.0, 1.0) < sim_.radio_loss_probability) continue;
        const double local = d.clock.local_from_true(t_rx);
        if (local >= 0.0 && local < local_end) rows.emplace_back(local, src);
      }
      std::stable_sort(rows.begin(), rows.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
      scene::SyncCsvWriter w((fs::path(out_dir) / spec.sync).string());
      for (const auto& [t, src] : rows) {
        RadioSync s;
        s.device = DeviceId(d.id);
        s.t_s = t;
        s.source = NameTag(src);
        w.write(s);
      }
      w.close();
    }
    sc.devices.push_back(std::move(spec));
  }
  for (const auto& e : sim_.emitters) {
    scene::EmitterSpec spec;
    spec.id = e.id;
    spec.emits = e.emits;
    if (e.anchor_position_m) spec.anchor_position_m = to_vec3(*e.anchor_position_m);
    sc.emitters.push_back(std::move(spec));
  }

  // truth.csv: static objects once at t = 0, moving ones every 1/truth_rate s
  {
    scene::TruthCsvWriter w((fs::path(out_dir) / "truth.csv").string());
    struct Obj {
      std::string id;
      const Trajectory* tr;
    };
    std::vector<Obj> objs;
    for (const auto& d : sim_.devices) objs.push_back({d.id, d.trajectory.get()});
    for (const auto& e : sim_.emitters) objs.push_back({e.id, e.trajectory.get()});
    const auto steps = static_cast<std::uint64_t>(std::floor(sim_.duration_s * sim_.truth_rate_hz));
    for (std::uint64_t k = 0; k <= steps; ++k) {
      const double t = static_cast<double>(k) / sim_.truth_rate_hz;
      for (const auto& o : objs)
        if (k == 0 || !o.tr->is_static()) w.write(truth_row(t, o.id, o.tr->pose(t)));
    }
    w.close();
  }
  // truth_emissions.csv: the emission schedule in true time
  {
    std::vector<const Emission*> ordered;
    for (const auto& e : sim_.emissions) ordered.push_back(&e);
    std::stable_sort(ordered.begin(), ordered.end(),
                     [](const Emission* a, const Emission* b) { return a->t_start_true_s() < b->t_start_true_s(); });
    scene::CsvWriter w((fs::path(out_dir) / "truth_emissions.csv").string(),
                       {"t_true", "id", "signal_index", "t_command", "latency_s"});
    for (const Emission* e : ordered)
      w.row({fmt(e->t_start_true_s()), e->source_id, std::to_string(e->signal_index), fmt(e->t_command_true_s),
             fmt(e->latency_s)});
    w.close();
  }
  for (const auto& [name, text] : sim_.extra_files) {  // evaluation-only extras (truth_steps.csv, ...)
    const fs::path path = fs::path(out_dir) / name;
    std::ofstream f(path, std::ios::binary);
    f << text;
    f.close();
    if (!f) throw std::runtime_error("cannot write " + path.string());
  }
  sc.truth = truth;
  scene::write_scene_yaml(sc);
  rep.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_begin).count();
  return rep;
}

}  // namespace locus::sim

