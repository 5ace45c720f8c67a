// The `multitone` detector: SpyLoc's beep receiver; algorithm in multitone.hpp.
#include "multitone.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <complex>
#include <cstdint>
#include <memory>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "locus/dsp/goertzel.hpp"
#include "locus/dsp/iir.hpp"
#include "locus/dsp/signals.hpp"

namespace locus::plugins::multitone {

std::array<float, 6> decay_times(std::span<const double> e, std::size_t peak_from, std::size_t peak_to,
                                 std::size_t end_index, double fs) noexcept {
  std::array<float, 6> out;
  out.fill(std::numeric_limits<float>::quiet_NaN());
  peak_to = std::min(peak_to, e.size());
  if (peak_from >= peak_to) return out;
  std::size_t ip = peak_from;
  for (std::size_t i = peak_from; i < peak_to; ++i)
    if (e[i] > e[ip]) ip = i;
  const double ref = e[ip];
  if (!(ref > 0.0)) return out;
  std::size_t i = ip;
  for (int k = 0; k < 6; ++k) {
    const double level = ref * std::pow(10.0, -0.5 * (k + 1));  // 5·(k+1) dB below
    while (i < e.size() && e[i] > level) ++i;
    if (i >= e.size()) break;
    out[k] = static_cast<float>((static_cast<double>(i) - static_cast<double>(end_index)) / fs);
  }
  return out;
}

namespace {

constexpr double kPi = std::numbers::pi;
using cf = std::complex<float>;

enum class State { idle, beep, tail };

struct Channel {
  std::vector<float> raw, bp;   // rings indexed by frame & mask
  dsp::SosFilter bpf;
  std::vector<double> floor;    // per tone
  std::vector<double> peak;     // per tone, during a beep
  std::uint64_t floor_n = 0;
  std::size_t since_hop = 0;
  State state = State::idle;
  int quiet_hops = 0;
  std::uint64_t open_frame = 0;   // hop end when the beep opened
  std::uint64_t ready_frame = 0;  // frame after which the tail is complete
  std::uint64_t start_frame = 0;  // first valid frame since restart
  std::uint64_t end_frame = 0;
  bool started = false;
};

class MultitoneDetector final : public Detector {
 public:
  void configure(const StreamInfo& info, const Params& params, HostContext& ctx) override {
    log_ = &ctx.log;
    device_ = info.device;
    detector_ = NameTag(ctx.instance);
    stream_ = info.stream;
    fs_ = info.sample_rate_hz;
    if (!(fs_ > 0)) throw std::runtime_error("multitone: sample rate must be > 0");
    if (info.channels == 0) throw std::runtime_error("multitone: the stream has no channels");
    channels_ = info.channels;
    tones_ = params.get_floats("tones_hz");
    if (tones_.empty() || tones_.size() > 16)
      throw std::runtime_error("multitone: tones_hz must list 1..16 tones, got " + std::to_string(tones_.size()));
    for (std::size_t k = 0; k < tones_.size(); ++k) {
      if (!(tones_[k] > 0.0 && tones_[k] < fs_ / 2.0))
        throw std::runtime_error("multitone: tones_hz[" + std::to_string(k) + "] = " + std::to_string(tones_[k]) +
                                 " Hz is outside (0, fs/2 = " + std::to_string(fs_ / 2.0) + ")");
      if (k > 0 && !(tones_[k] > tones_[k - 1]))
        throw std::runtime_error("multitone: tones_hz must be strictly increasing (entry " + std::to_string(k) + ")");
    }
    duration_s_ = params.get_float("duration_s");
    fade_s_ = params.get_float("fade_s");
    if (2.0 * fade_s_ > duration_s_)
      throw std::runtime_error("multitone: 2·fade_s (" + std::to_string(2 * fade_s_) + " s) exceeds duration_s (" +
                               std::to_string(duration_s_) + " s)");
    frame_ = static_cast<std::size_t>(std::llround(params.get_float("frame_s") * fs_));
    hop_ = std::max<std::size_t>(1, static_cast<std::size_t>(std::llround(params.get_float("hop_s") * fs_)));
    if (frame_ < 16) throw std::runtime_error("multitone: frame_s is shorter than 16 samples");
    thr_ = std::pow(10.0, params.get_float("threshold_db") / 10.0);
    min_tones_ = static_cast<int>(params.get_int("min_tones"));
    tail_ = static_cast<std::size_t>(std::llround(params.get_float("tail_s") * fs_));
    smooth_ = std::max<std::size_t>(1, static_cast<std::size_t>(std::llround(params.get_float("smoothing_s") * fs_)));
    beta_ = 1.0 - std::exp(-static_cast<double>(hop_) / (params.get_float("floor_time_constant_s") * fs_));
    warmup_hops_ = static_cast<std::uint64_t>(std::ceil(params.get_float("warmup_s") * fs_ / static_cast<double>(hop_)));

    bank_ = dsp::GoertzelBank(tones_, fs_);
    const double kt = static_cast<double>(tones_.size());
    sum_thr_ = kt + 7.0 * std::sqrt(kt) + 4.0;
    win_.resize(frame_);
    for (std::size_t i = 0; i < frame_; ++i) win_[i] = static_cast<float>(0.5 - 0.5 * std::cos(2 * kPi * (i + 0.5) / frame_));
    const double spacing = tones_.size() > 1 ? tones_[1] - tones_[0] : 250.0;
    sos_ = dsp::butter_bandpass(4, std::max(1.0, tones_.front() - spacing), std::min(fs_ / 2.0 * 0.999, tones_.back() + spacing), fs_);

    // Matched-filter templates per tone (envelope w(t) of the format, cos and sin parts).
    len_ = static_cast<std::size_t>(std::llround(duration_s_ * fs_));
    search_ = static_cast<std::int64_t>(frame_ + 2 * hop_ + static_cast<std::size_t>(fade_s_ * fs_));
    nfft_ = std::bit_ceil(len_ + 2 * static_cast<std::size_t>(search_) + 1);
    fft_ = ctx.fft.plan_real(nfft_);
    const std::size_t nb = nfft_ / 2 + 1;
    spec_c_.assign(tones_.size(), std::vector<cf>(nb));
    spec_s_.assign(tones_.size(), std::vector<cf>(nb));
    std::vector<float> buf(nfft_);
    tone_energy_ = 0.0;
    for (std::size_t k = 0; k < tones_.size(); ++k) {
      for (int part = 0; part < 2; ++part) {
        std::fill(buf.begin(), buf.end(), 0.0f);
        for (std::size_t n = 0; n < len_; ++n) {
          const double t = static_cast<double>(n) / fs_;
          const double w = dsp::fade_weight(t, duration_s_, fade_s_);
          const double ph = 2 * kPi * tones_[k] * t;
          buf[n] = static_cast<float>(w * (part == 0 ? std::cos(ph) : std::sin(ph)));
          if (k == 0 && part == 0) tone_energy_ += w * w / 2.0;
        }
        fft_->forward(buf.data(), part == 0 ? spec_c_[k].data() : spec_s_[k].data());
      }
    }
    tone_c_.assign(tones_.size() * len_, 0.0f);
    tone_s_.assign(tones_.size() * len_, 0.0f);
    for (std::size_t k = 0; k < tones_.size(); ++k)
      for (std::size_t n = 0; n < len_; ++n) {
        const double t = static_cast<double>(n) / fs_;
        const double w = dsp::fade_weight(t, duration_s_, fade_s_);
        tone_c_[k * len_ + n] = static_cast<float>(w * std::cos(2 * kPi * tones_[k] * t));
        tone_s_[k * len_ + n] = static_cast<float>(w * std::sin(2 * kPi * tones_[k] * t));
      }
    double hann2 = 0.0;
    for (float v : win_) hann2 += static_cast<double>(v) * v;
    corr_per_frame_ = 2.0 * tone_energy_ / hann2;
    const std::size_t span = static_cast<std::size_t>(search_) + len_ + tail_ + 2 * frame_ + smooth_;
    ring_size_ = std::bit_ceil(2 * (span + nfft_) + info.max_block_frames + 4 * frame_ + 2 * hop_);
    ring_mask_ = ring_size_ - 1;
    chans_.assign(channels_, Channel{});
    for (Channel& ch : chans_) {
      ch.raw.assign(ring_size_, 0.0f);
      ch.bp.assign(ring_size_, 0.0f);
      ch.bpf = dsp::SosFilter(sos_);
      ch.floor.assign(tones_.size(), 0.0);
      ch.peak.assign(tones_.size(), 0.0);
    }
    frame_buf_.assign(frame_, 0.0f);
    pow_.assign(tones_.size(), 0.0);
    seg_.assign(nfft_, 0.0f);
    spec_y_.assign(nb, cf{});
    spec_a_.assign(nb, cf{});
    spec_b_.assign(nb, cf{});
    spec_w_.assign(nb, cf{});
    re_.assign(nfft_, 0.0f);
    im_.assign(nfft_, 0.0f);
    env_.assign(len_ + tail_ + 2 * smooth_ + 2, 0.0);
    expected_ = 0;
    have_expected_ = false;
    dropped_ = 0;
  }

  void process_audio(const AudioBlock& block, EventSink& out) noexcept override {
    const bool gap = block.lost_before > 0 || (have_expected_ && block.first_frame != expected_);
    const std::uint32_t nch = std::min(block.channels, channels_);
    for (std::uint32_t c = 0; c < nch; ++c) {
      Channel& ch = chans_[c];
      if (gap) ch.started = false;  // a beep in progress across a gap is dropped
      if (!ch.started) restart(ch, block.first_frame);
      const float* x = block.channel_data[c];
      for (std::uint32_t i = 0; i < block.frames; ++i) {
        const std::uint64_t f = block.first_frame + i;
        ch.raw[f & ring_mask_] = x[i];
        ch.bp[f & ring_mask_] = ch.bpf.process(x[i]);
        ch.end_frame = f + 1;
        if (++ch.since_hop == hop_) {
          ch.since_hop = 0;
          hop(c, out);
        }
      }
    }
    expected_ = block.first_frame + block.frames;
    have_expected_ = true;
  }

  void finish(EventSink& out) override {
    for (std::uint32_t c = 0; c < channels_; ++c) {
      Channel& ch = chans_[c];
      if (ch.started && ch.state != State::idle && ch.end_frame >= ch.ready_frame) finalize(c, out);
    }
    if (dropped_ > 0 && log_) log_->warn("multitone: " + std::to_string(dropped_) + " events dropped (event queue full)");
  }

 private:
  void restart(Channel& ch, std::uint64_t frame) noexcept {
    ch.bpf.reset();
    std::fill(ch.floor.begin(), ch.floor.end(), 0.0);
    ch.floor_n = 0;
    ch.since_hop = 0;
    ch.state = State::idle;
    ch.start_frame = frame;
    ch.end_frame = frame;
    ch.started = true;
  }

  void hop(std::uint32_t c, EventSink& out) noexcept {
    Channel& ch = chans_[c];
    if (ch.end_frame - ch.start_frame < frame_) return;
    const std::uint64_t first = ch.end_frame - frame_;
    for (std::size_t i = 0; i < frame_; ++i) frame_buf_[i] = ch.raw[(first + i) & ring_mask_] * win_[i];
    bank_.compute(frame_buf_, pow_.data());
    const bool warm = ch.floor_n >= warmup_hops_;
    int above = 0;
    double sum = 0.0;
    for (std::size_t k = 0; k < tones_.size(); ++k) {
      above += pow_[k] > thr_ * ch.floor[k];
      sum += pow_[k] / std::max(ch.floor[k], 1e-30);
    }
    // Either enough single tones clear the threshold, or the tone set's summed normalised power
    // does (many weak tones): under noise the sum is Gamma(K, 1), K + 7·sqrt(K) is far in its tail.
    const bool active = warm && (above >= min_tones_ || sum > sum_thr_);
    switch (ch.state) {
      case State::idle:
        if (active) {
          ch.state = State::beep;
          ch.open_frame = ch.end_frame;
          ch.quiet_hops = 0;
          std::copy(pow_.begin(), pow_.end(), ch.peak.begin());
        } else {
          for (std::size_t k = 0; k < tones_.size(); ++k) {
            const double b = std::max(beta_, 1.0 / static_cast<double>(ch.floor_n + 1));
            ch.floor[k] += b * (pow_[k] - ch.floor[k]);
          }
          ++ch.floor_n;
        }
        break;
      case State::beep:
        for (std::size_t k = 0; k < tones_.size(); ++k) ch.peak[k] = std::max(ch.peak[k], pow_[k]);
        ch.quiet_hops = active ? 0 : ch.quiet_hops + 1;
        if (ch.quiet_hops >= 2 || ch.end_frame - ch.open_frame > len_ + frame_) {
          ch.state = State::tail;
          // Coarse onset ≈ open_frame − frame/2; the last sample needed by the analysis:
          ch.ready_frame = ch.open_frame + static_cast<std::uint64_t>(search_) + len_ + tail_ + smooth_ + nfft_;
        }
        break;
      case State::tail:
        if (ch.end_frame >= ch.ready_frame) finalize(c, out);
        break;
    }
  }

  // Envelope maximum of the matched filter of `mask` over the segment whose spectrum is spec_y_;
  // returns the lag (segment index), its envelope and the parabolic offset.
  std::size_t locate(std::uint32_t mask, double& best_e, double& off) noexcept {
    const std::size_t nb = nfft_ / 2 + 1;
    std::fill(spec_a_.begin(), spec_a_.end(), cf{});
    std::fill(spec_b_.begin(), spec_b_.end(), cf{});
    for (std::size_t k = 0; k < tones_.size(); ++k) {
      if (!(mask & (1u << k))) continue;
      for (std::size_t b = 0; b < nb; ++b) {
        spec_a_[b] += spec_c_[k][b];
        spec_b_[b] += spec_s_[k][b];
      }
    }
    for (std::size_t b = 0; b < nb; ++b) spec_w_[b] = spec_y_[b] * std::conj(spec_a_[b]);
    fft_->inverse(spec_w_.data(), re_.data());
    for (std::size_t b = 0; b < nb; ++b) spec_w_[b] = spec_y_[b] * std::conj(spec_b_[b]);
    fft_->inverse(spec_w_.data(), im_.data());
    const std::size_t lags = std::min<std::size_t>(2 * static_cast<std::size_t>(search_) + 1, nfft_ - len_ + 1);
    std::size_t best = 0;
    best_e = -1.0;
    auto env = [&](std::size_t l) { return std::hypot(static_cast<double>(re_[l]), static_cast<double>(im_[l])); };
    for (std::size_t l = 0; l < lags; ++l) {
      const double e = env(l);
      if (e > best_e) {
        best_e = e;
        best = l;
      }
    }
    off = 0.0;
    if (best > 0 && best + 1 < lags) {
      const double a = env(best - 1), b = best_e, d = env(best + 1);
      const double den = a - 2 * b + d;
      if (den < 0) off = std::clamp(0.5 * (a - d) / den, -0.5, 0.5);
    }
    return best;
  }

  // Tones on at arrival frame `at`: full-length per-tone correlation power over its noise
  // expectation (from the tone-bank floor) above threshold_db, and within 6 dB of the strongest
  // tone (the tones of a beep have equal amplitudes). snr_db: mean over the tones on;
  // confidence: fraction of them more than threshold_db above that.
  std::uint32_t tone_mask_at(const Channel& ch, std::uint64_t at, double& snr_db, double& conf) noexcept {
    double pmax = 0.0;
    for (std::size_t k = 0; k < tones_.size(); ++k) {
      const float* tc = &tone_c_[k * len_];
      const float* ts = &tone_s_[k * len_];
      double re = 0.0, im = 0.0;
      for (std::size_t n = 0; n < len_; ++n) {
        const float y = ch.raw[(at + n) & ring_mask_];
        re += y * tc[n];
        im += y * ts[n];
      }
      pow_[k] = re * re + im * im;
      pmax = std::max(pmax, pow_[k]);
    }
    std::uint32_t mask = 0;
    double sum = 0.0;
    int on = 0, strong = 0;
    for (std::size_t k = 0; k < tones_.size(); ++k) {
      const double noise = std::max(ch.floor[k], 1e-30) * corr_per_frame_;
      if (pow_[k] > thr_ * noise && pow_[k] > 0.25 * pmax) {
        mask |= 1u << k;
        const double r = 10.0 * std::log10(pow_[k] / noise);
        sum += r;
        ++on;
        strong += pow_[k] > thr_ * thr_ * noise;
      }
    }
    snr_db = on > 0 ? sum / on : 0.0;
    conf = on > 0 ? static_cast<double>(strong) / on : 0.0;
    return mask;
  }

  void finalize(std::uint32_t c, EventSink& out) noexcept {
    Channel& ch = chans_[c];
    ch.state = State::idle;
    std::uint32_t mask = 0;
    for (std::size_t k = 0; k < tones_.size(); ++k)
      if (ch.peak[k] > thr_ * std::max(ch.floor[k], 1e-30)) mask |= 1u << k;
    if (mask == 0) mask = (1u << tones_.size()) - 1u;  // opened by the summed power: try every tone
    // Matched filter around the coarse onset.
    const std::int64_t coarse = static_cast<std::int64_t>(ch.open_frame) - static_cast<std::int64_t>(frame_ / 2);
    const std::int64_t seg0 = coarse - search_;
    if (seg0 < static_cast<std::int64_t>(ch.start_frame) ||
        static_cast<std::uint64_t>(seg0) + nfft_ > ch.end_frame ||
        static_cast<std::uint64_t>(seg0) + ring_size_ < ch.end_frame)
      return;  // not enough contiguous audio around it
    for (std::size_t i = 0; i < nfft_; ++i) seg_[i] = ch.raw[(static_cast<std::uint64_t>(seg0) + i) & ring_mask_];
    fft_->forward(seg_.data(), spec_y_.data());
    double best_e = 0.0, off = 0.0;
    std::size_t best = locate(mask, best_e, off);
    // Identity from the full-length per-tone matched filters at the arrival (≈ 20 dB more gain than
    // one tone-bank frame); a changed identity gets a second arrival search with its template.
    double snr_db = 0.0, conf = 0.0;
    const std::uint32_t mask2 = tone_mask_at(ch, static_cast<std::uint64_t>(seg0) + best, snr_db, conf);
    if (mask2 == 0) {
      ++rejected_;
      return;  // no tone of the set clears the full-length matched filter: not a beep
    }
    if (mask2 != mask) {
      mask = mask2;
      best = locate(mask, best_e, off);
      tone_mask_at(ch, static_cast<std::uint64_t>(seg0) + best, snr_db, conf);
    }
    const double arrival = static_cast<double>(seg0) + static_cast<double>(best) + off;
    // Amplitude: correlation peak = a/K · K tones · Σw²/2 / nfft scaling (unnormalised inverse).
    const double amp = best_e / static_cast<double>(nfft_) / tone_energy_;

    AudioDetection d;
    d.device = device_;
    d.detector = detector_;
    d.stream = stream_;
    d.channel = static_cast<std::uint16_t>(c);
    d.template_index = static_cast<std::uint16_t>(mask);
    d.frame = arrival;
    d.sample_rate_hz = fs_;
    d.snr_db = static_cast<float>(snr_db);
    d.confidence = static_cast<float>(conf);
    d.amplitude = static_cast<float>(amp);
    if (!out.emit(Event{d})) ++dropped_;

    // Decay features on the smoothed band-passed energy.
    DecayFeatures f;
    f.device = device_;
    f.detector = detector_;
    f.stream = stream_;
    f.channel = d.channel;
    f.template_index = d.template_index;
    f.frame = arrival;
    f.sample_rate_hz = fs_;
    const std::int64_t a0 = static_cast<std::int64_t>(std::floor(arrival));
    const std::size_t n_env = len_ + tail_;
    const std::int64_t from = a0 - static_cast<std::int64_t>(smooth_ / 2);
    if (from >= static_cast<std::int64_t>(ch.start_frame) &&
        static_cast<std::uint64_t>(from) + n_env + smooth_ <= ch.end_frame) {
      double acc = 0.0;
      for (std::size_t i = 0; i < smooth_; ++i) {
        const float v = ch.bp[(static_cast<std::uint64_t>(from) + i) & ring_mask_];
        acc += static_cast<double>(v) * v;
      }
      for (std::size_t i = 0; i < n_env; ++i) {
        env_[i] = acc / static_cast<double>(smooth_);  // centred on frame a0 + i
        const float vin = ch.bp[(static_cast<std::uint64_t>(from) + smooth_ + i) & ring_mask_];
        const float vout = ch.bp[(static_cast<std::uint64_t>(from) + i) & ring_mask_];
        acc += static_cast<double>(vin) * vin - static_cast<double>(vout) * vout;
      }
      f.decay_s = decay_times(std::span<const double>(env_.data(), n_env), 0, len_, len_, fs_);
      // Noise: the band energy just before the beep.
      double noise = 0.0;
      const std::size_t pre = std::min<std::size_t>(frame_, static_cast<std::size_t>(std::max<std::int64_t>(0, from - static_cast<std::int64_t>(ch.start_frame))));
      for (std::size_t i = 1; i <= pre; ++i) {
        const float v = ch.bp[(static_cast<std::uint64_t>(from) - i) & ring_mask_];
        noise += static_cast<double>(v) * v;
      }
      double peak = 0.0;
      for (std::size_t i = 0; i < len_; ++i) peak = std::max(peak, env_[i]);
      f.noise_margin_db = pre > 0 && noise > 0 ? static_cast<float>(10.0 * std::log10(peak / (noise / pre))) : kNaN;
    }
    if (!out.emit(Event{f})) ++dropped_;
  }

  Logger* log_ = nullptr;
  DeviceId device_;
  NameTag detector_;
  std::uint32_t stream_ = 0;
  std::uint32_t channels_ = 0;
  double fs_ = 44100.0;
  std::vector<double> tones_;
  double duration_s_ = 0.05, fade_s_ = 0.005;
  std::size_t frame_ = 441, hop_ = 110, len_ = 0, tail_ = 0, smooth_ = 1, nfft_ = 0;
  std::int64_t search_ = 0;
  double thr_ = 10.0, beta_ = 0.01;
  int min_tones_ = 1;
  std::uint64_t warmup_hops_ = 1;
  dsp::GoertzelBank bank_;
  std::vector<float> win_;
  std::vector<dsp::Biquad> sos_;
  std::unique_ptr<RealFft> fft_;
  std::vector<std::vector<cf>> spec_c_, spec_s_;
  double tone_energy_ = 1.0;
  double corr_per_frame_ = 1.0;
  double sum_thr_ = 1e300;
  std::uint64_t rejected_ = 0;  // Σw² (beep envelope) / Σhann² (tone-bank frame): noise scaling
  std::vector<float> tone_c_, tone_s_;  // per tone, len_ samples: w(n)·cos / w(n)·sin
  std::size_t ring_size_ = 0, ring_mask_ = 0;
  std::vector<Channel> chans_;
  std::vector<float> frame_buf_, seg_, re_, im_;
  std::vector<double> pow_, env_;
  std::vector<cf> spec_y_, spec_a_, spec_b_, spec_w_;
  std::uint64_t expected_ = 0;
  bool have_expected_ = false;
  std::uint64_t dropped_ = 0;
};

const ParamSchema* schema_fn() { return &schema(); }
Detector* create() { return new MultitoneDetector(); }

}  // namespace

const ParamSchema& schema() {
  static const ParamSchema schema = {
      float_list_param("tones_hz",
                       std::vector<double>{18000, 18250, 18500, 18750, 19000, 19250, 19500, 19750, 20000, 20250},
                       1.0, 100000.0, "Hz", "Tone set f_0..f_{K-1}; bit k of a beacon's identity switches f_k on (SpyLoc: 10 tones, 250 Hz apart).",
                       1, 16),
      float_param("duration_s", 0.05, 0.002, 2.0, "s", "Beep duration (the emitters' multitone `duration`)."),
      float_param("fade_s", 0.005, 0.0, 1.0, "s", "Raised-cosine fade of the beep (the emitters' `fade`)."),
      float_param("frame_s", 0.01, 0.0005, 0.5, "s", "Tone-bank analysis frame (Hann window)."),
      float_param("hop_s", 0.0025, 0.0001, 0.5, "s", "Tone-bank hop."),
      float_param("threshold_db", 12.0, 1.0, 80.0, "dB", "A tone is on when its power exceeds its noise floor by this."),
      int_param("min_tones", std::int64_t{1}, 1, 16, "", "Tones that must be on to open a beep."),
      float_param("floor_time_constant_s", 1.0, 0.01, 3600.0, "s", "Time constant of the per-tone noise floors."),
      float_param("warmup_s", 0.05, 0.0, 60.0, "s", "Noise floors learnt for this long before the first beep."),
      float_param("tail_s", 0.15, 0.0, 5.0, "s", "Reverberation tail analysed after the beep (decay features)."),
      float_param("smoothing_s", 0.002, 0.0001, 0.1, "s", "Moving-average length of the energy envelope."),
  };
  return schema;
}

const locus_plugin_descriptor* descriptor() {
  static const locus_plugin_descriptor d{
      LOCUS_PLUGIN_ABI_VERSION,
      LOCUS_PLUGIN_DETECTOR,
      "multitone",
      "0.1.0",
      "SpyLoc multitone beeps: tone-bank identity (MAC bits), matched-filter arrival, decay features T5..T30",
      kInputAudio,
      &schema_fn,
      &create,
      nullptr,
  };
  return &d;
}

}  // namespace locus::plugins::multitone
