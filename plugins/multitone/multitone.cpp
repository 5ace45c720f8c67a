// The `multitone` detector: SpyLoc's beep receiver; algorithm in multitone.hpp.
#include "multitone.hpp"

#include <algorithm>
#include <array>
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
#include "locus/dsp/onset_fit.hpp"
#include "locus/dsp/signals.hpp"
#include "locus/numbers.hpp"

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

using cf = std::complex<float>;
constexpr std::size_t kMaxPending = 8;
constexpr std::size_t kOs = 8;  // fine-fit grid: 1/kOs sample
constexpr std::size_t kMaxBodyHops = 64;  // body hops kept for the identity's median
constexpr std::uint32_t kLongAgo = 1u << 30;  // hop counters saturate here ("never")

// [RT] Median (upper middle) of v[0..n), reordering it in place; 0 when n = 0.
double median_in_place(double* v, std::size_t n) noexcept {
  if (n == 0) return 0.0;
  std::nth_element(v, v + n / 2, v + n);
  return v[n / 2];
}

struct Pending {
  std::uint64_t open_frame = 0;   // hop end when the beep opened
  std::uint64_t ready_frame = 0;  // frame after which all the audio it needs is in the ring
  std::array<double, 16> level{};  // median tone-bank power over the body, per tone
  std::array<double, 16> head{};   // ... over its first half (a burst may cover the rest of the beep)
  std::array<double, 16> floor{};  // floors when it opened
  bool opened_active = false;      // the tone set was already active when it opened (a burst, a tail)
};

struct Channel {
  std::vector<float> raw;       // ring indexed by frame & mask
  std::vector<double> floor;    // per tone
  std::vector<double> body;     // per body hop (up to kMaxBodyHops), per tone: tone-bank power
  std::uint64_t floor_n = 0;
  std::size_t since_hop = 0;
  bool in_body = false;
  bool was_active = false;
  int body_hops = 0;
  int quiet_hops = 0;
  std::uint64_t hops_since_active = 1u << 30;
  std::uint64_t active_run = 0;
  std::array<double, 4> sum_hist{};  // summed normalised power of the last hops
  std::uint64_t open_frame = 0;
  std::uint64_t last_open = 0;
  bool opened_once = false;
  bool last_body_short = false;  // the last body was active for less than half a beep: a blip, not a beep
  bool body_pattern = false;      // a candidate's tone pattern showed in the body's first hops
  bool body_opened_active = false;  // the tone set was active on the hop before the body opened
  bool last_pattern = false;      // ... in the last body opened
  std::vector<std::uint32_t> pat_high_run;   // per candidate: hops in a row its contrast is over pattern_db
  std::vector<std::uint32_t> pat_since_low;  // per candidate: hops since its contrast was under pattern_low_db
  std::array<Pending, kMaxPending> pending{};
  std::size_t pend_head = 0, pend_n = 0;
  std::uint64_t start_frame = 0;  // first valid frame since restart
  std::uint64_t end_frame = 0;
  std::uint64_t last_det_open = 0;  // open frame of the body of the last beep reported
  std::uint32_t last_det_mask = 0;  // ... and its identity (0: none yet)
  bool started = false;
};

// The tone set of a multitone SignalSpec as bits of `tones` (-1 when a tone is not in the set).
long mask_of(const std::vector<double>& tones, const std::vector<double>& spec_tones) {
  long m = 0;
  for (double f : spec_tones) {
    long k = -1;
    for (std::size_t i = 0; i < tones.size(); ++i)
      if (std::fabs(tones[i] - f) < 0.5) k = static_cast<long>(i);
    if (k < 0) return -1;
    m |= 1L << k;
  }
  return m;
}

class MultitoneDetector final : public Detector {
 public:
  // [main]
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
    candidates_.clear();
    for (double v : params.get_floats("identities")) {
      const long m = std::lround(v);
      if (std::fabs(v - static_cast<double>(m)) > 1e-9 || m <= 0 || m >= (1L << tones_.size()))
        throw std::runtime_error("multitone: identities entry " + std::to_string(v) + " is not a tone mask in 1.." +
                                 std::to_string((1L << tones_.size()) - 1));
      candidates_.push_back(static_cast<std::uint32_t>(m));
    }
    if (params.get_bool("from_scene") && ctx.geometry != nullptr) {
      bool timing = false;
      for (const SceneSignal& e : ctx.geometry->scene_emits) {
        if (e.signal.type != "multitone") continue;
        const long m = mask_of(tones_, e.signal.tones_hz);
        if (m <= 0)
          throw std::runtime_error("multitone: scene emitter " + std::string(e.id) +
                                   ": a tone of its multitone is not in tones_hz");
        if (std::find(candidates_.begin(), candidates_.end(), static_cast<std::uint32_t>(m)) == candidates_.end())
          candidates_.push_back(static_cast<std::uint32_t>(m));
        if (!timing) {
          duration_s_ = e.signal.duration_s;
          fade_s_ = e.signal.fade_s;
          timing = true;
        } else if (std::fabs(duration_s_ - e.signal.duration_s) > 1e-9 || std::fabs(fade_s_ - e.signal.fade_s) > 1e-9) {
          throw std::runtime_error("multitone: the scene's multitone emitters differ in duration/fade; one detector "
                                   "handles one beep length");
        }
      }
      ctx.log.info("multitone: " + std::to_string(candidates_.size()) + " identities from the scene");
    }
    if (!(duration_s_ > 0)) throw std::runtime_error("multitone: duration_s must be > 0");
    if (2.0 * fade_s_ > duration_s_)
      throw std::runtime_error("multitone: 2·fade_s (" + std::to_string(2 * fade_s_) + " s) exceeds duration_s (" +
                               std::to_string(duration_s_) + " s)");
    frame_ = static_cast<std::size_t>(std::llround(params.get_float("frame_s") * fs_));
    hop_ = std::max<std::size_t>(1, static_cast<std::size_t>(std::llround(params.get_float("hop_s") * fs_)));
    if (frame_ < 16) throw std::runtime_error("multitone: frame_s is shorter than 16 samples");
    thr_db_ = params.get_float("threshold_db");
    thr_ = std::pow(10.0, thr_db_ / 10.0);
    id_db_ = params.get_float("identity_db");
    coherent_ = params.get_string("fit_phase") == "known";
    min_tones_ = static_cast<int>(params.get_int("min_tones"));
    tail_ = static_cast<std::size_t>(std::llround(params.get_float("tail_s") * fs_));
    smooth_ = std::max<std::size_t>(1, static_cast<std::size_t>(std::llround(params.get_float("smoothing_s") * fs_)));
    beta_ = 1.0 - std::exp(-static_cast<double>(hop_) / (params.get_float("floor_time_constant_s") * fs_));
    warmup_hops_ = static_cast<std::uint64_t>(std::ceil(params.get_float("warmup_s") * fs_ / static_cast<double>(hop_)));
    hold_hops_ = static_cast<std::uint64_t>(std::ceil(params.get_float("hold_s") * fs_ / static_cast<double>(hop_)));
    max_active_hops_ = static_cast<std::uint64_t>(std::ceil(params.get_float("max_active_s") * fs_ / static_cast<double>(hop_)));
    rise_ = std::pow(10.0, params.get_float("rise_db") / 10.0);
    pat_db_ = params.get_float("pattern_db");
    pat_low_db_ = params.get_float("pattern_low_db");
    if (!(pat_low_db_ < pat_db_))
      throw std::runtime_error("multitone: pattern_low_db must be below pattern_db");
    rel_ = std::pow(10.0, -params.get_float("relative_db") / 10.0);
    onset_thr_ = std::pow(10.0, params.get_float("onset_threshold_db") / 10.0);
    weak_onset_thr_ = std::min(onset_thr_, std::pow(10.0, params.get_float("weak_onset_threshold_db") / 10.0));
    fit_len_ = static_cast<std::size_t>(std::llround(params.get_float("fit_window_s") * fs_));
    paths_opt_ = dsp::OnsetPathsFit::Options{};
    paths_opt_.oversample = kOs;
    paths_opt_.scan_step = params.get_float("path_scan_samples");
    paths_opt_.max_paths = static_cast<std::size_t>(params.get_int("max_paths"));
    paths_opt_.threshold = std::pow(10.0, params.get_float("path_threshold_db") / 10.0);
    paths_opt_.tolerance = params.get_float("path_tolerance");
    paths_opt_.back = std::round(params.get_float("path_search_s") * fs_);
    carrier_phase_ = params.get_bool("carrier_phase");
    paths_opt_.known_phase_cycle = params.get_string("cycle_choice") == "known_phase";
    doppler_ = params.get_bool("doppler");

    bank_ = dsp::GoertzelBank(tones_, fs_);
    const double kt = static_cast<double>(tones_.size());
    sum_thr_ = kt + 7.0 * std::sqrt(kt) + 4.0;
    win_.resize(frame_);
    for (std::size_t i = 0; i < frame_; ++i) win_[i] = static_cast<float>(0.5 - 0.5 * std::cos(2 * kPi * (i + 0.5) / frame_));
    double spacing = tones_.size() > 1 ? tones_[1] - tones_[0] : 250.0;
    for (std::size_t k = 2; k < tones_.size(); ++k) spacing = std::min(spacing, tones_[k] - tones_[k - 1]);
    doppler_len_ = static_cast<std::size_t>(std::llround(2.0 * fs_ / spacing));  // two periods of the tone grid
    sos_ = dsp::butter_bandpass(4, std::max(1.0, tones_.front() - spacing), std::min(fs_ / 2.0 * 0.999, tones_.back() + spacing), fs_);

    len_ = static_cast<std::size_t>(std::llround(duration_s_ * fs_));
    onset_len_ = std::min(len_, static_cast<std::size_t>(std::llround(fs_ / spacing)));
    pre_ = onset_len_ / 4;  // search margin before the leading edge (samples before τ do not enter the fit)
    fit_len_ = std::min(fit_len_, len_);
    if (fit_len_ < 8) throw std::runtime_error("multitone: fit_window_s is shorter than 8 samples");
    search_ = static_cast<std::int64_t>(frame_ + 2 * hop_ + static_cast<std::size_t>(fade_s_ * fs_));
    noise_len_ = static_cast<std::size_t>(std::llround(0.02 * fs_));
    nfft_ = std::bit_ceil(noise_len_ + onset_len_ + 2 * static_cast<std::size_t>(search_) + 1);
    fft_ = ctx.fft.plan_real(nfft_);
    const std::size_t nb = nfft_ / 2 + 1;
    spec_c_.assign(tones_.size(), std::vector<cf>(nb));
    spec_s_.assign(tones_.size(), std::vector<cf>(nb));
    std::vector<float> buf(nfft_);
    // Onset templates per tone (first onset_len_ samples of the beep; cos and sin parts) for the FFT
    // onset statistic, and finely sampled (1/kOs sample) over the fit window for the LS fit.
    for (std::size_t k = 0; k < tones_.size(); ++k) {
      for (int part = 0; part < 2; ++part) {
        std::fill(buf.begin(), buf.end(), 0.0f);
        for (std::size_t n = 0; n < onset_len_; ++n) {
          const double t = static_cast<double>(n) / fs_;
          const double ph = 2 * kPi * tones_[k] * t;
          buf[n] = static_cast<float>(dsp::fade_weight(t, duration_s_, fade_s_) * (part == 0 ? std::sin(ph) : std::cos(ph)));
        }
        fft_->forward(buf.data(), part == 0 ? spec_c_[k].data() : spec_s_[k].data());
      }
    }
    fine_n_ = (std::max(fit_len_ + 2 * pre_ + 2 * onset_len_ + 68,
                        static_cast<std::size_t>(paths_opt_.back) + 2 * pre_ +
                            static_cast<std::size_t>(std::llround(params.get_float("path_window_s") * fs_)) + 68)) * kOs;
    fine_s_.assign(tones_.size() * fine_n_, 0.0f);
    fine_c_.assign(tones_.size() * fine_n_, 0.0f);
    for (std::size_t k = 0; k < tones_.size(); ++k)
      for (std::size_t i = 0; i < fine_n_; ++i) {
        const double t = static_cast<double>(i) / (static_cast<double>(kOs) * fs_);
        const double w = dsp::fade_weight(t, duration_s_, fade_s_);
        fine_s_[k * fine_n_ + i] = static_cast<float>(w * std::sin(2 * kPi * tones_[k] * t));
        fine_c_[k * fine_n_ + i] = static_cast<float>(w * std::cos(2 * kPi * tones_[k] * t));
      }
    tone_energy_ = 0.0;
    for (std::size_t n = 0; n < len_; ++n) {
      const double w = dsp::fade_weight(static_cast<double>(n) / fs_, duration_s_, fade_s_);
      tone_energy_ += w * w / 2.0;
    }
    // Ring: from the noise reference before the search range to the end of the decay window.
    before_ = static_cast<std::size_t>(search_) + noise_len_ + frame_;
    after_ = static_cast<std::size_t>(search_) + len_ + tail_ + 2 * smooth_ + nfft_ + fit_len_ + 2 * frame_;
    ring_size_ = std::bit_ceil(2 * (before_ + after_) + info.max_block_frames + 4 * frame_ + 2 * hop_ + pre_);
    ring_mask_ = ring_size_ - 1;
    chans_.assign(channels_, Channel{});
    for (Channel& ch : chans_) {
      ch.raw.assign(ring_size_, 0.0f);
      ch.floor.assign(tones_.size(), 0.0);
      ch.body.assign(kMaxBodyHops * tones_.size(), 0.0);
      ch.pat_high_run.assign(candidates_.size(), 0);
      ch.pat_since_low.assign(candidates_.size(), kLongAgo);
    }
    lvl_db_.assign(tones_.size(), 0.0);
    frame_buf_.assign(frame_, 0.0f);
    pow_.assign(tones_.size(), 0.0);
    seg_.assign(nfft_, 0.0f);
    spec_y_.assign(nb, cf{});
    spec_w_.assign(nb, cf{});
    re_.assign(nfft_, 0.0f);
    im_.assign(nfft_, 0.0f);
    stat_.assign(nfft_, 0.0);
    sorted_.assign(nfft_, 0.0);
    mt_s_.assign(fine_n_, 0.0f);
    ph_stride_ = (fine_n_ + kOs - 1) / kOs;
    for (std::size_t r = 0; r < kOs; ++r) ph_len_[r] = r < fine_n_ ? (fine_n_ - r + kOs - 1) / kOs : 0;
    ph_s_.assign(kOs * ph_stride_, 0.0f);
    ph_c_.assign(kOs * ph_stride_, 0.0f);
    ph_ss_.assign(kOs * (ph_stride_ + 1), 0.0);
    ph_cc_.assign(kOs * (ph_stride_ + 1), 0.0);
    ph_sc_.assign(kOs * (ph_stride_ + 1), 0.0);
    mt_c_.assign(fine_n_, 0.0f);
    win_y_.assign(fit_len_ + 2 * pre_ + 2 * onset_len_ + 64, 0.0f);
    // Multipath window: back samples before the single-path estimate (and pre_ more), fit_len_ after.
    paths_opt_.known_phase = coherent_;
    const auto path_win = static_cast<std::size_t>(std::llround(params.get_float("path_window_s") * fs_));
    paths_opt_.ahead = std::max(0.0, static_cast<double>(path_win) - 16.0);
    paths_len_ = static_cast<std::size_t>(paths_opt_.back) + pre_ + path_win;
    if (paths_opt_.max_paths > 1 && paths_len_ + 1 > fine_n_ / kOs)
      throw std::runtime_error("multitone: path_search_s + fit_window_s is too long for the onset templates");
    paths_buf_.assign(std::max(paths_len_, noise_len_) + 1, 0.0f);
    paths_.reserve(paths_buf_.size());
    dop_prefix_.assign(len_ + 1, {});
    env_.assign(len_ + tail_ + 2 * smooth_ + 2, 0.0);
    settle_ = static_cast<std::size_t>(std::llround(0.01 * fs_));
    bp_buf_.assign(frame_ + settle_ + len_ + tail_ + 2 * smooth_ + 4, 0.0f);
    bpf_ = dsp::SosFilter(sos_);
    expected_ = 0;
    have_expected_ = false;
    dropped_ = 0;
  }

  // [RT]
  void process_audio(const AudioBlock& block, EventSink& out) noexcept override {
    const bool gap = block.lost_before > 0 || (have_expected_ && block.first_frame != expected_);
    const std::uint32_t nch = std::min(block.channels, channels_);
    for (std::uint32_t c = 0; c < nch; ++c) {
      Channel& ch = chans_[c];
      if (gap) ch.started = false;  // beeps in progress across a gap are dropped
      if (!ch.started) restart(ch, block.first_frame);
      const float* x = block.channel_data[c];
      for (std::uint32_t i = 0; i < block.frames; ++i) {
        const std::uint64_t f = block.first_frame + i;
        ch.raw[f & ring_mask_] = x[i];
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

  // [main]
  void finish(EventSink& out) override {
    for (std::uint32_t c = 0; c < channels_; ++c) {
      Channel& ch = chans_[c];
      if (!ch.started) continue;
      if (ch.in_body) close_body(ch);
      while (ch.pend_n > 0) {
        finalize(c, ch.pending[ch.pend_head], out);
        ch.pend_head = (ch.pend_head + 1) % kMaxPending;
        --ch.pend_n;
      }
    }
    if (dropped_ > 0 && log_) log_->warn("multitone: " + std::to_string(dropped_) + " events dropped (event queue full)");
    if (overflow_ > 0 && log_) log_->warn("multitone: " + std::to_string(overflow_) + " beeps dropped (more than 8 awaiting analysis)");
    if (log_)
      log_->info("multitone: " + std::to_string(rejected_) + " bodies rejected (no identity or leading edge), " +
                 std::to_string(split_) + " interferer bodies yielded to a beep's tone pattern, " + std::to_string(weak_edges_) +
                 " leading edges at weak_onset_threshold_db");
  }

 private:
  void restart(Channel& ch, std::uint64_t frame) noexcept {
    std::fill(ch.floor.begin(), ch.floor.end(), 0.0);
    ch.floor_n = 0;
    ch.since_hop = 0;
    ch.in_body = false;
    ch.was_active = false;
    ch.hops_since_active = 1u << 30;
    ch.active_run = 0;
    ch.sum_hist.fill(0.0);
    ch.pend_n = 0;
    ch.pend_head = 0;
    ch.opened_once = false;
    ch.body_pattern = false;
    ch.last_pattern = false;
    ch.last_det_mask = 0;
    std::fill(ch.pat_high_run.begin(), ch.pat_high_run.end(), 0u);
    std::fill(ch.pat_since_low.begin(), ch.pat_since_low.end(), kLongAgo);
    ch.start_frame = frame;
    ch.end_frame = frame;
    ch.started = true;
  }

  void close_body(Channel& ch) noexcept {
    ch.in_body = false;
    if (ch.pend_n == kMaxPending) {
      ++overflow_;
      return;
    }
    Pending& p = ch.pending[(ch.pend_head + ch.pend_n) % kMaxPending];
    ++ch.pend_n;
    p.open_frame = ch.open_frame;
    p.ready_frame = ch.open_frame + after_;
    p.opened_active = ch.body_opened_active;
    const std::size_t n = std::min<std::size_t>(static_cast<std::size_t>(std::max(ch.body_hops, 1)), kMaxBodyHops);
    const std::size_t nh = std::max<std::size_t>(std::min<std::size_t>(n, 3), n / 2);
    for (std::size_t k = 0; k < tones_.size(); ++k) {
      // Median over the body hops: the frames on the beep's edges (fade splatter into neighbouring
      // tones) and a burst of noise do not move it.
      p.level[k] = body_median(ch, k, n);
      p.head[k] = body_median(ch, k, nh);
      p.floor[k] = ch.floor[k];
    }
  }

  // [RT] Median of tone k's power over the first n body hops.
  double body_median(const Channel& ch, std::size_t k, std::size_t n) noexcept {
    for (std::size_t h = 0; h < n; ++h) med_[h] = ch.body[h * tones_.size() + k];
    return median_in_place(med_.data(), n);
  }

  // [RT] One tone-bank hop: floors, opening and closing of beeps, analysis of the ready ones.
  void hop(std::uint32_t c, EventSink& out) noexcept {
    Channel& ch = chans_[c];
    while (ch.pend_n > 0 && ch.end_frame >= ch.pending[ch.pend_head].ready_frame) {
      finalize(c, ch.pending[ch.pend_head], out);
      ch.pend_head = (ch.pend_head + 1) % kMaxPending;
      --ch.pend_n;
    }
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
    const bool rising = active && sum > rise_ * ch.sum_hist[2] && ch.sum_hist[2] > 0.0;
    for (std::size_t i = ch.sum_hist.size() - 1; i > 0; --i) ch.sum_hist[i] = ch.sum_hist[i - 1];
    ch.sum_hist[0] = sum;
    bool pattern_now = false;
    const bool pattern_edge = warm && candidate_pattern(ch, pattern_now);
    if (ch.in_body && ch.body_hops < 4 && pattern_now) ch.body_pattern = true;
    if (ch.in_body && pattern_edge && active && !ch.body_pattern) {
      // A candidate's tone pattern starts inside a body that showed none at its start: an
      // interferer's burst keeps the tone set active, so that body opened on the burst. It is dropped
      // and the beep gets its own body from here (its identity and search range on the beep).
      ++split_;
      open_body(ch, pattern_now);
    } else if (ch.in_body) {
      if (static_cast<std::size_t>(ch.body_hops) < kMaxBodyHops)
        std::copy(pow_.begin(), pow_.end(), ch.body.begin() + static_cast<std::ptrdiff_t>(ch.body_hops * tones_.size()));
      ++ch.body_hops;
      ch.quiet_hops = active ? 0 : ch.quiet_hops + 1;
      if (ch.quiet_hops >= 2 || ch.end_frame - ch.open_frame > len_) {
        ch.last_body_short =
            ch.quiet_hops >= 2 && 2 * static_cast<std::size_t>(ch.body_hops - ch.quiet_hops) * hop_ < len_;  // active hops
        close_body(ch);
      }
    } else if (active && (((!ch.was_active || rising) &&
                           (!ch.opened_once || ch.end_frame - ch.last_open > len_ + frame_ || (ch.last_body_short && rising))) ||
                          (pattern_edge && !ch.last_pattern))) {
      // A new beep opens a beep's length after the last one opened (its own tail and echoes must not
      // open another), or sooner on a clear rise when the last body was a blip, active for less than
      // half a beep (an interferer's burst just before a beep: spyloc-104's beeps 101 and 102, 33 dB
      // over the floor, were lost behind babble blips 2000 samples earlier), or when a candidate's
      // tone pattern starts and the last body showed none (a beep inside an interferer's burst).
      open_body(ch, pattern_now);
    }
    ch.was_active = active;
    ch.hops_since_active = active ? 0 : ch.hops_since_active + 1;
    ch.active_run = active ? ch.active_run + 1 : 0;
    // Floors: only well away from any activity (beeps and their tails), or slowly inside a long one.
    // Inside a long activity (an interferer's burst: bodies open on it back to back) they learn in
    // bodies too, each hop's power clipped at 6 dB over the floor, so that a beep inside the burst
    // moves them by less than a dB while the burst's level is followed within about a second.
    // Digital silence (a stream that starts before its source is connected: every tone exactly 0)
    // teaches them nothing: floors learnt on it would sit at 0 and the clip would hold them there
    // (a live walker under load lost half its beeps so).
    bool silent = true;
    for (std::size_t k = 0; k < tones_.size() && silent; ++k) silent = !(pow_[k] > 0.0);
    const bool long_activity = warm && ch.active_run > max_active_hops_;
    const bool learn = !silent && ((!ch.in_body && (!warm || ch.hops_since_active > hold_hops_)) || long_activity);
    if (learn) {
      for (std::size_t k = 0; k < tones_.size(); ++k) {
        const double b = std::max(beta_, 1.0 / static_cast<double>(ch.floor_n + 1));
        const double v = long_activity && ch.floor[k] > 0.0 ? std::min(pow_[k], 4.0 * ch.floor[k]) : pow_[k];
        ch.floor[k] += b * (v - ch.floor[k]);
      }
      ++ch.floor_n;
    }
  }

  // [RT] Opens a body at this hop (the previous one, if any, is dropped unanalysed).
  void open_body(Channel& ch, bool pattern_now) noexcept {
    ch.in_body = true;
    ch.opened_once = true;
    ch.open_frame = ch.end_frame;
    ch.last_open = ch.end_frame;
    ch.quiet_hops = 0;
    ch.body_hops = 1;
    ch.body_pattern = pattern_now;
    ch.last_pattern = pattern_now;
    ch.body_opened_active = ch.was_active;
    std::copy(pow_.begin(), pow_.end(), ch.body.begin());
  }

  // [RT] Per candidate identity, the contrast of its tones over the others (mean levels over the
  // floors, dB): a broadband interferer raises every tone alike, a beep only its own. Sets
  // `pattern_now` when some candidate's contrast is over pattern_db for two hops in a row (one such
  // hop happens by chance under a burst); returns true on a pattern's
  // start: a candidate over pattern_db for a second hop in a row, under pattern_low_db within the
  // three hops before that run began.
  bool candidate_pattern(Channel& ch, bool& pattern_now) noexcept {
    if (candidates_.empty()) return false;
    for (std::size_t k = 0; k < tones_.size(); ++k)
      lvl_db_[k] = 10.0 * std::log10(std::max(pow_[k], 1e-30) / std::max(ch.floor[k], 1e-30));
    bool edge = false;
    for (std::size_t j = 0; j < candidates_.size(); ++j) {
      const std::uint32_t m = candidates_[j];
      double in = 0.0, out = 0.0;
      int n_in = 0, n_out = 0;
      for (std::size_t k = 0; k < tones_.size(); ++k) {
        if ((m >> k) & 1u) {
          in += lvl_db_[k];
          ++n_in;
        } else {
          out += lvl_db_[k];
          ++n_out;
        }
      }
      const double contrast = in / std::max(n_in, 1) - (n_out > 0 ? out / n_out : 0.0);
      std::uint32_t& run = ch.pat_high_run[j];
      std::uint32_t& since_low = ch.pat_since_low[j];
      since_low = contrast < pat_low_db_ ? 0 : std::min<std::uint32_t>(since_low + 1, kLongAgo);
      run = contrast > pat_db_ ? run + 1 : 0;
      pattern_now = pattern_now || run >= 2;
      edge = edge || (run == 2 && since_low <= 5);
    }
    return edge;
  }

  // [RT] Identity of a beep from its per-tone body levels; 0 = not a beep of the set. With
  // candidates, `background_db` = the median level (dB over the floors, >= 0) of the tones outside
  // the chosen one: what an interferer's burst raised alike.
  std::uint32_t identity(const Pending& p, const std::array<double, 16>& level, double& snr_db, double& conf,
                         double& background_db) noexcept {
    double lmax = 0.0, pmax = 0.0;
    std::array<double, 16> l{};
    background_db = 0.0;
    for (std::size_t k = 0; k < tones_.size(); ++k) {
      l[k] = 10.0 * std::log10(std::max(level[k], 1e-30) / std::max(p.floor[k], 1e-30));
      lmax = std::max(lmax, l[k]);
      pmax = std::max(pmax, level[k]);
    }
    std::uint32_t mask = 0;
    for (std::size_t k = 0; k < tones_.size(); ++k)
      if (l[k] > id_db_ && level[k] > rel_ * pmax) mask |= 1u << k;
    if (mask == 0) return 0;
    conf = 1.0;
    if (!candidates_.empty()) {
      double best = -1e300, second = -1e300;
      std::uint32_t arg = 0;
      for (std::uint32_t m : candidates_) {
        double sc = 0.0;
        for (std::size_t k = 0; k < tones_.size(); ++k) sc += ((m >> k) & 1u ? 1.0 : -1.0) * (l[k] - 0.5 * lmax);
        if (sc > best) {
          second = best;
          best = sc;
          arg = m;
        } else if (sc > second) {
          second = sc;
        }
      }
      // The candidate must explain the strong tones: every tone within 10 dB of the strongest is in
      // it, unless that tone is no more than 6 dB over the median of the tones outside it (an
      // interferer's burst raises every tone alike; another beacon's tone stands out of them).
      std::size_t n_out = 0, n_in = 0;
      for (std::size_t k = 0; k < tones_.size(); ++k)
        if (!((arg >> k) & 1u)) out_db_[n_out++] = l[k];
      const double background = std::max(0.0, median_in_place(out_db_.data(), n_out));
      background_db = background;
      for (std::size_t k = 0; k < tones_.size(); ++k)
        if (l[k] > lmax - 10.0 && l[k] > id_db_ && l[k] > background + 6.0 && !((arg >> k) & 1u)) return 0;
      // ... and its own tones stand out of that background (median 6 dB over it: not the burst alone).
      for (std::size_t k = 0; k < tones_.size(); ++k)
        if ((arg >> k) & 1u) out_db_[n_in++] = l[k];
      if (n_in == 0 || !(median_in_place(out_db_.data(), n_in) > background + 6.0)) return 0;
      mask = arg;
      conf = candidates_.size() > 1 ? std::clamp((best - second) / std::max(lmax, 1e-9), 0.0, 1.0) : 1.0;
    }
    double sum = 0.0;
    int on = 0, strong = 0;
    for (std::size_t k = 0; k < tones_.size(); ++k) {
      if (!((mask >> k) & 1u)) continue;
      sum += l[k];
      ++on;
      strong += l[k] > 2.0 * thr_db_;
    }
    snr_db = on > 0 ? sum / on : 0.0;
    conf *= on > 0 ? static_cast<double>(strong) / on : 0.0;
    return mask;
  }

  // [RT] Doppler time scale 1 + η of the beep body ch.raw[start, start + n): per identity tone, the
  // mean phase advance between demodulated windows of two tone-grid periods (the other tones of the
  // grid null out), hop_doppler_ apart (unambiguous up to ±fs/(2·hop) Hz), over ω·hop gives η;
  // weighted by the windows' power. 1 when the body is too short or holds no tone.
  double doppler_scale(const Channel& ch, std::int64_t start, std::size_t n, std::uint32_t mask) noexcept {
    const std::size_t lw = doppler_len_, h = std::max<std::size_t>(1, doppler_len_ / 4);
    n = std::min(n, dop_prefix_.size() - 1);
    if (start < static_cast<std::int64_t>(ch.start_frame) || static_cast<std::uint64_t>(start) + n > ch.end_frame || n < lw + 2 * h)
      return 1.0;
    double num = 0.0, den = 0.0;
    for (std::size_t k = 0; k < tones_.size(); ++k) {
      if (!((mask >> k) & 1u)) continue;
      const double w = 2.0 * kPi * tones_[k] / fs_;
      // Prefix sums of the demodulated body: each window's sum is a difference of two.
      const std::complex<double> rot = std::polar(1.0, -w);
      std::complex<double> ph = 1.0, acc_sum = 0.0;
      dop_prefix_[0] = 0.0;
      for (std::size_t i = 0; i < n; ++i) {
        acc_sum += static_cast<double>(ch.raw[(static_cast<std::uint64_t>(start) + i) & ring_mask_]) * ph;
        dop_prefix_[i + 1] = acc_sum;
        ph *= rot;
        if ((i & 255u) == 255u) ph /= std::abs(ph);  // keep the phasor on the unit circle
      }
      std::complex<double> acc = 0.0, prev = 0.0;
      for (std::size_t m = 0; m * h + lw <= n; ++m) {
        const std::complex<double> z = dop_prefix_[m * h + lw] - dop_prefix_[m * h];
        if (m > 0) acc += z * std::conj(prev);
        prev = z;
      }
      const double mag = std::abs(acc);
      if (!(mag > 0.0)) continue;
      num += mag * std::arg(acc) / (w * static_cast<double>(h));
      den += mag;
    }
    return den > 0.0 ? 1.0 + std::clamp(num / den, -0.01, 0.01) : 1.0;
  }

  // [RT] Projected energy of the window win_y_[0..nw) onto the onset model starting at offset
  // `tau8` (in 1/kOs samples from the window start); amplitude estimate in `amp`.
  // The template is read by phase (ph_s_/ph_c_: for phase r, its points r, r + kOs, ...), contiguous,
  // and its energies over a range come from the prefix sums ph_ss_/ph_cc_/ph_sc_: the loop is two
  // products per sample.
  double fit_energy(std::size_t nw, std::int64_t tau8, double& amp) const noexcept {
    // Window sample n meets template point u = n·kOs − tau8 (from the first n with u >= 0).
    const auto k8 = static_cast<std::int64_t>(kOs);
    const std::int64_t n0 = tau8 <= 0 ? 0 : (tau8 + k8 - 1) / k8;
    const std::int64_t u0 = n0 * k8 - tau8;
    const auto r = static_cast<std::size_t>(u0 % k8), j0 = static_cast<std::size_t>(u0 / k8);
    const std::size_t per = ph_len_[r];
    if (static_cast<std::size_t>(n0) >= nw || j0 >= per) {
      amp = 0.0;
      return 0.0;
    }
    const std::size_t count = std::min(nw - static_cast<std::size_t>(n0), per - j0);
    const float* ps = &ph_s_[r * ph_stride_ + j0];
    const float* pc = &ph_c_[r * ph_stride_ + j0];
    const float* py = &win_y_[static_cast<std::size_t>(n0)];
    // Four partial sums each: the additions' latency, not the products, bounds one chain.
    double ys4[4] = {0.0, 0.0, 0.0, 0.0}, yc4[4] = {0.0, 0.0, 0.0, 0.0};
    std::size_t i = 0;
    for (; i + 4 <= count; i += 4)
      for (std::size_t k = 0; k < 4; ++k) {
        const double y = py[i + k];
        ys4[k] += y * ps[i + k];
        yc4[k] += y * pc[i + k];
      }
    for (; i < count; ++i) {
      ys4[0] += static_cast<double>(py[i]) * ps[i];
      yc4[0] += static_cast<double>(py[i]) * pc[i];
    }
    const double ys = (ys4[0] + ys4[1]) + (ys4[2] + ys4[3]), yc = (yc4[0] + yc4[1]) + (yc4[2] + yc4[3]);
    const std::size_t base = r * (ph_stride_ + 1);
    const double ss = ph_ss_[base + j0 + count] - ph_ss_[base + j0];
    const double cc = ph_cc_[base + j0 + count] - ph_cc_[base + j0];
    const double sc = ph_sc_[base + j0 + count] - ph_sc_[base + j0];
    if (coherent_) {  // known carrier phase: one real amplitude (sign free)
      amp = ss > 1e-30 ? std::fabs(ys) / ss : 0.0;
      return ss > 1e-30 ? ys * ys / ss : 0.0;
    }
    const double det = ss * cc - sc * sc;
    if (!(det > 1e-30)) {
      amp = 0.0;
      return 0.0;
    }
    const double a = (cc * ys - sc * yc) / det, b = (ss * yc - sc * ys) / det;
    amp = std::sqrt(a * a + b * b);
    return a * ys + b * yc;
  }

  // [RT] Analysis of one closed beep: identity, leading edge, onset fit, decay features.
  void finalize(std::uint32_t c, const Pending& p, EventSink& out) noexcept {
    Channel& ch = chans_[c];
    double snr_db = 0.0, conf = 0.0;
    double background_db = 0.0;
    std::uint32_t mask = identity(p, p.level, snr_db, conf, background_db);
    // An interferer's burst that starts during the beep covers the rest of its body: its first half.
    if (mask == 0 && !candidates_.empty()) mask = identity(p, p.head, snr_db, conf, background_db);
    if (mask == 0) {
      ++rejected_;
      return;
    }
    // Segment: noise reference, then the search range around the coarse onset.
    const std::int64_t coarse = static_cast<std::int64_t>(p.open_frame) - static_cast<std::int64_t>(frame_);
    const std::int64_t seg0 = coarse - search_ - static_cast<std::int64_t>(noise_len_);
    if (seg0 < static_cast<std::int64_t>(ch.start_frame) || static_cast<std::uint64_t>(seg0) + nfft_ > ch.end_frame ||
        static_cast<std::uint64_t>(seg0) + ring_size_ < ch.end_frame + pre_)
      return;  // not enough contiguous audio around it
    for (std::size_t i = 0; i < nfft_; ++i) seg_[i] = ch.raw[(static_cast<std::uint64_t>(seg0) + i) & ring_mask_];
    fft_->forward(seg_.data(), spec_y_.data());
    const std::size_t nb = nfft_ / 2 + 1;
    for (int part = 0; part < 2; ++part) {
      std::fill(spec_w_.begin(), spec_w_.end(), cf{});
      for (std::size_t k = 0; k < tones_.size(); ++k) {
        if (!((mask >> k) & 1u)) continue;
        const std::vector<cf>& t = part == 0 ? spec_c_[k] : spec_s_[k];
        for (std::size_t b = 0; b < nb; ++b) spec_w_[b] += spec_y_[b] * std::conj(t[b]);
      }
      fft_->inverse(spec_w_.data(), part == 0 ? re_.data() : im_.data());
    }
    const std::size_t lags = nfft_ - onset_len_ + 1;
    for (std::size_t l = 0; l < lags; ++l)
      stat_[l] = static_cast<double>(re_[l]) * re_[l] + static_cast<double>(im_[l]) * im_[l];
    // Noise: median of the statistic over the lags whose template lies in the noise reference.
    const std::size_t nn = noise_len_ - onset_len_;
    std::copy(stat_.begin(), stat_.begin() + static_cast<std::ptrdiff_t>(nn), sorted_.begin());
    std::nth_element(sorted_.begin(), sorted_.begin() + static_cast<std::ptrdiff_t>(nn / 2), sorted_.begin() + static_cast<std::ptrdiff_t>(nn));
    const double noise = std::max(sorted_[nn / 2] / std::log(2.0), 1e-30);  // exponential: mean = median / ln 2
    // The leading edge: the first lag over the threshold that the beep's energy follows — at least half
    // of the next 3 onset lengths stay within 6 dB of the threshold. A burst shorter than that (an
    // interferer's blip in the search window) is not a beep's start.
    std::size_t edge = lags;
    const std::size_t sustain = 3 * onset_len_;
    // With candidates the identity already says a beep is there; under an interferer's burst (the
    // tones outside the identity over identity_db; the noise reference is the burst) its onset may
    // not clear onset_threshold_db: a second pass at weak_onset_threshold_db, the same sustain rule.
    // Also when the body opened while the tone set was already active (a burst whose tones outside
    // the identity stay low), unless it is the last reported beep's own tail.
    // (Not in a quiet beep's tail: its reflections would be timed as a first path.)
    const bool own_tail = mask == ch.last_det_mask && p.open_frame < ch.last_det_open + len_ + tail_;
    const int passes_edge = !candidates_.empty() && (background_db > 3.0 || (p.opened_active && !own_tail)) ? 2 : 1;
    for (int pe = 0; pe < passes_edge && edge == lags; ++pe) {
      const double thr = (pe == 0 ? onset_thr_ : weak_onset_thr_) * noise;
      for (std::size_t l = noise_len_; l < lags; ++l) {
        if (!(stat_[l] > thr)) continue;
        const std::size_t end = std::min(lags, l + sustain);
        std::size_t on = 0;
        for (std::size_t q = l; q < end; ++q) on += stat_[q] > 0.25 * thr;
        if (end - l < sustain || 2 * on >= end - l) {
          edge = l;
          weak_edges_ += pe;
          break;
        }
      }
    }
    if (edge == lags) {
      ++rejected_;
      return;
    }
    // Onset fit: identity's fine templates.
    std::fill(mt_s_.begin(), mt_s_.end(), 0.0f);
    std::fill(mt_c_.begin(), mt_c_.end(), 0.0f);
    for (std::size_t k = 0; k < tones_.size(); ++k) {
      if (!((mask >> k) & 1u)) continue;
      for (std::size_t i = 0; i < fine_n_; ++i) {
        mt_s_[i] += fine_s_[k * fine_n_ + i];
        mt_c_[i] += fine_c_[k * fine_n_ + i];
      }
    }
    // ... by phase, with the prefix sums of their energies (fit_energy).
    for (std::size_t r = 0; r < kOs; ++r) {
      const std::size_t b = r * (ph_stride_ + 1);
      double ss = 0.0, cc = 0.0, sc = 0.0;
      ph_ss_[b] = ph_cc_[b] = ph_sc_[b] = 0.0;
      for (std::size_t j = 0; j < ph_len_[r]; ++j) {
        const double sv = mt_s_[r + j * kOs], cv = mt_c_[r + j * kOs];
        ph_s_[r * ph_stride_ + j] = static_cast<float>(sv);
        ph_c_[r * ph_stride_ + j] = static_cast<float>(cv);
        ss += sv * sv;
        cc += cv * cv;
        sc += sv * cv;
        ph_ss_[b + j + 1] = ss;
        ph_cc_[b + j + 1] = cc;
        ph_sc_[b + j + 1] = sc;
      }
    }
    double centre = static_cast<double>(seg0) + static_cast<double>(edge);  // absolute frame estimate
    double amp = 0.0;
    // Passes: (range before, range after the current estimate in samples, step in 1/kOs samples).
    const std::int64_t passes[3][3] = {{static_cast<std::int64_t>(onset_len_ + pre_), static_cast<std::int64_t>(onset_len_), 8},
                                       {24, 24, 2},
                                       {3, 3, 1}};
    for (int pass = 0; pass < 3; ++pass) {
      const std::int64_t c0 = static_cast<std::int64_t>(std::floor(centre));
      // Fixed window for all candidates of the pass: pre_ before the estimate to fit_len_ after it.
      // (pass 0: from pre_ before the earliest to fit_len_ after the latest candidate).
      const std::int64_t w0 = c0 - passes[pass][0] * (pass == 0) - static_cast<std::int64_t>(pre_);
      const std::size_t nw = std::min(static_cast<std::size_t>(c0 + (pass == 0 ? passes[0][1] : 0) - w0) + fit_len_, win_y_.size());
      if (w0 < static_cast<std::int64_t>(ch.start_frame) || static_cast<std::uint64_t>(w0) + nw > ch.end_frame) return;
      for (std::size_t n = 0; n < nw; ++n) win_y_[n] = ch.raw[(static_cast<std::uint64_t>(w0) + n) & ring_mask_];
      const std::int64_t step = passes[pass][2];
      const std::int64_t k8 = static_cast<std::int64_t>(kOs);
      std::int64_t best = 0;
      double best_e = -1.0, e_prev = -1.0, e_next = -1.0, prev = -1.0;
      bool want_next = false;
      for (std::int64_t t8 = (c0 - passes[pass][0] - w0) * k8; t8 <= (c0 + passes[pass][1] - w0) * k8; t8 += step) {
        double a = 0.0;
        const double e = fit_energy(nw, t8, a);
        if (want_next) {
          e_next = e;
          want_next = false;
        }
        if (e > best_e) {
          best_e = e;
          best = t8;
          e_prev = prev;
          amp = a;
          want_next = true;
          e_next = -1.0;
        }
        prev = e;
      }
      double off = 0.0;
      if (pass == 2 && e_prev >= 0.0 && e_next >= 0.0) {
        const double den = e_prev - 2 * best_e + e_next;
        if (den < 0) off = std::clamp(0.5 * (e_prev - e_next) / den, -0.5, 0.5) * static_cast<double>(step);
      }
      centre = static_cast<double>(w0) + (static_cast<double>(best) + off) / static_cast<double>(kOs);
    }
    double arrival = centre, timing_conf = 1.0, envelope = 0.0, period = 0.0;
    // Multipath onset fit (dsp::OnsetPathsFit): the window from path_search_s before the single-path
    // estimate to fit_window_s after it as up to max_paths delayed beeps; the first needed path is
    // the direct one (the single-path fit is pulled towards the floor/ceiling echoes).
    if (paths_opt_.max_paths > 1) {
      const std::int64_t w0 = static_cast<std::int64_t>(std::floor(centre)) - static_cast<std::int64_t>(paths_opt_.back) -
                              static_cast<std::int64_t>(pre_);
      if (w0 >= static_cast<std::int64_t>(ch.start_frame) && static_cast<std::uint64_t>(w0) + paths_len_ <= ch.end_frame) {
        // The noise reference before the search range (from the ring: the FFT may have used seg_).
        for (std::size_t i = 0; i < noise_len_; ++i) paths_buf_[i] = ch.raw[(static_cast<std::uint64_t>(seg0) + i) & ring_mask_];
        const double noise_var = paths_.noise_power(paths_buf_.data(), noise_len_, mt_c_.data(), mt_s_.data(), fine_n_, paths_opt_);
        for (std::size_t n = 0; n < paths_len_; ++n) paths_buf_[n] = ch.raw[(static_cast<std::uint64_t>(w0) + n) & ring_mask_];
        dsp::OnsetPathsFit::Options opt = paths_opt_;
        const std::size_t fade_n = static_cast<std::size_t>(std::llround(fade_s_ * fs_));
        if (doppler_ && len_ > 2 * fade_n + 64)
          opt.time_scale = doppler_scale(ch, static_cast<std::int64_t>(std::floor(centre)) + static_cast<std::int64_t>(fade_n) + 16,
                                         len_ - 2 * fade_n - 32, mask);
        if (carrier_phase_) {
          double wsum = 0.0;
          for (std::size_t k = 0; k < tones_.size(); ++k)
            if ((mask >> k) & 1u) wsum += tones_[k];
          opt.carrier_rad = 2.0 * kPi * wsum / std::max(1, std::popcount(mask)) / fs_ * opt.time_scale;
        }
        const dsp::OnsetPathsFit::Result r = paths_.fit(paths_buf_.data(), paths_len_, mt_c_.data(), mt_s_.data(), fine_n_,
                                                        centre - static_cast<double>(w0), noise_var, opt);
        if (r.paths > 0) {
          arrival = static_cast<double>(w0) + r.first;
          if (opt.carrier_rad > 0.0) {
            envelope = static_cast<double>(w0) + r.envelope_first;
            period = 2.0 * kPi / opt.carrier_rad;
          }
          timing_conf = r.confidence;
          amp = r.first_amplitude;
        }
      }
    }

    AudioDetection d;
    d.device = device_;
    d.detector = detector_;
    d.stream = stream_;
    d.channel = static_cast<std::uint16_t>(c);
    d.template_index = static_cast<std::uint16_t>(mask);
    d.frame = arrival;
    d.sample_rate_hz = fs_;
    d.snr_db = static_cast<float>(snr_db);
    d.confidence = static_cast<float>(std::min(conf, timing_conf));
    d.amplitude = static_cast<float>(amp / std::max(1, std::popcount(mask)));
    d.envelope_frame = envelope;
    d.carrier_period = static_cast<float>(period);
    if (!out.emit(Event{d})) ++dropped_;
    ch.last_det_open = p.open_frame;
    ch.last_det_mask = mask;

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
      // Band-pass only where needed (not per sample in the stream): from the noise window before the
      // beep, after settle_ samples for the filter's transient, to the end of the decay window.
      const std::int64_t b0 = std::max<std::int64_t>(static_cast<std::int64_t>(ch.start_frame),
                                                     from - static_cast<std::int64_t>(frame_ + settle_));
      const std::int64_t b1 = from + static_cast<std::int64_t>(n_env + smooth_);
      bpf_.reset();
      for (std::int64_t k = b0; k < b1; ++k)
        bp_buf_[static_cast<std::size_t>(k - b0)] = bpf_.process(ch.raw[static_cast<std::uint64_t>(k) & ring_mask_]);
      auto bp = [&](std::int64_t k) { return bp_buf_[static_cast<std::size_t>(k - b0)]; };
      double acc = 0.0;
      for (std::size_t i = 0; i < smooth_; ++i) {
        const float v = bp(from + static_cast<std::int64_t>(i));
        acc += static_cast<double>(v) * v;
      }
      for (std::size_t i = 0; i < n_env; ++i) {
        env_[i] = acc / static_cast<double>(smooth_);  // centred on frame a0 + i
        const float vin = bp(from + static_cast<std::int64_t>(smooth_ + i));
        const float vout = bp(from + static_cast<std::int64_t>(i));
        acc += static_cast<double>(vin) * vin - static_cast<double>(vout) * vout;
      }
      f.decay_s = decay_times(std::span<const double>(env_.data(), n_env), 0, len_, len_, fs_);
      double noise_e = 0.0;
      const std::size_t pre = std::min<std::size_t>(frame_, static_cast<std::size_t>(std::max<std::int64_t>(0, from - b0)));
      for (std::size_t i = 1; i <= pre; ++i) {
        const float v = bp(from - static_cast<std::int64_t>(i));
        noise_e += static_cast<double>(v) * v;
      }
      double peak = 0.0;
      for (std::size_t i = 0; i < len_; ++i) peak = std::max(peak, env_[i]);
      f.noise_margin_db = pre > 0 && noise_e > 0 ? static_cast<float>(10.0 * std::log10(peak / (noise_e / pre))) : kNaN;
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
  std::vector<std::uint32_t> candidates_;
  double duration_s_ = 0.05, fade_s_ = 0.005;
  std::size_t frame_ = 441, hop_ = 110, len_ = 0, tail_ = 0, smooth_ = 1, nfft_ = 0;
  std::size_t onset_len_ = 176, fit_len_ = 176, pre_ = 60, noise_len_ = 882, fine_n_ = 0, before_ = 0, after_ = 0;
  std::int64_t search_ = 0;
  double thr_ = 10.0, thr_db_ = 10.0, id_db_ = 6.0, beta_ = 0.01, rise_ = 4.0, rel_ = 0.003, onset_thr_ = 30.0;
  double pat_db_ = 12.0, pat_low_db_ = 4.0, weak_onset_thr_ = 8.0;
  std::uint64_t weak_edges_ = 0;
  std::vector<double> lvl_db_;  // per tone: power over floor this hop, dB
  int min_tones_ = 1;
  bool coherent_ = false;
  std::uint64_t warmup_hops_ = 1, hold_hops_ = 1, max_active_hops_ = 1;
  dsp::GoertzelBank bank_;
  std::vector<float> win_;
  std::vector<dsp::Biquad> sos_;
  std::unique_ptr<RealFft> fft_;
  std::vector<std::vector<cf>> spec_c_, spec_s_;
  std::vector<float> fine_s_, fine_c_, mt_s_, mt_c_, win_y_, bp_buf_, paths_buf_;
  std::vector<float> ph_s_, ph_c_;            // mt_s_/mt_c_ by phase (fit_energy)
  std::vector<double> ph_ss_, ph_cc_, ph_sc_;  // ... their energies' prefix sums per phase
  std::array<std::size_t, kOs> ph_len_{};
  std::size_t ph_stride_ = 0;
  dsp::OnsetPathsFit paths_;
  dsp::OnsetPathsFit::Options paths_opt_;
  std::size_t paths_len_ = 0;
  bool carrier_phase_ = true, doppler_ = true;
  std::size_t doppler_len_ = 353;
  std::vector<std::complex<double>> dop_prefix_;
  dsp::SosFilter bpf_;
  std::size_t settle_ = 441;
  double tone_energy_ = 1.0;
  double sum_thr_ = 1e300;
  std::uint64_t rejected_ = 0, overflow_ = 0, split_ = 0;
  std::size_t ring_size_ = 0, ring_mask_ = 0;
  std::vector<Channel> chans_;
  std::vector<float> frame_buf_, seg_, re_, im_;
  std::vector<double> pow_, env_, stat_, sorted_;
  std::array<double, kMaxBodyHops> med_{};
  std::array<double, 16> out_db_{};  // identity's scratch: levels in / outside a candidate
  std::vector<cf> spec_y_, spec_w_;
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
      float_param("hop_s", 0.005, 0.0001, 0.5, "s", "Tone-bank hop."),
      float_param("threshold_db", 12.0, 1.0, 80.0, "dB", "A tone is on when its power exceeds its noise floor by this."),
      int_param("min_tones", std::int64_t{1}, 1, 16, "", "Tones that must be on to open a beep."),
      float_param("floor_time_constant_s", 1.0, 0.01, 3600.0, "s", "Time constant of the per-tone noise floors."),
      float_param("warmup_s", 0.05, 0.0, 60.0, "s", "Noise floors learnt for this long before the first beep."),
      float_param("tail_s", 0.15, 0.0, 5.0, "s", "Reverberation tail analysed after the beep (decay features)."),
      float_param("smoothing_s", 0.002, 0.0001, 0.1, "s", "Moving-average length of the energy envelope."),
      float_list_param("identities", std::vector<double>{}, 1.0, 65535.0, "",
                       "Candidate identities (tone masks, bit k = tones_hz[k]); empty = the measured tone set.", 0, 64),
      bool_param("from_scene", false, "Identities, duration_s and fade_s from the scene's multitone emitters (replay)."),
      float_param("hold_s", 0.15, 0.0, 10.0, "s", "Floors learn only this long after the last tone activity (beep tails)."),
      float_param("max_active_s", 0.6, 0.05, 60.0, "s", "Activity longer than this is not a beep: floors learn through it."),
      float_param("rise_db", 6.0, 1.0, 40.0, "dB", "Rise of the summed tone power within 3 hops that opens a beep on a tail."),
      float_param("pattern_db", 12.0, 3.0, 60.0, "dB",
                  "With candidate identities: a candidate's tones over the other tones by this (mean levels over the floors) "
                  "for two hops marks a beep's start inside an interferer's burst, which keeps the tone set active."),
      float_param("pattern_low_db", 4.0, 0.0, 40.0, "dB",
                  "... after its contrast was under this within the three hops before (the pattern's start, not its tail)."),
      float_param("identity_db", 6.0, 1.0, 80.0, "dB", "A tone is in the identity when its mean power over the beep body exceeds its floor by this."),
      float_param("relative_db", 25.0, 3.0, 80.0, "dB", "A tone is on only within this of the strongest tone (Doppler leakage, fading)."),
      float_param("onset_threshold_db", 15.0, 3.0, 60.0, "dB", "Leading edge: onset statistic over its noise level."),
      float_param("weak_onset_threshold_db", 7.0, 3.0, 60.0, "dB",
                  "With candidate identities, a beep whose identity holds but whose onset does not clear onset_threshold_db "
                  "(an interferer's burst as the noise reference) is searched again at this."),
      enum_param("fit_phase", "free", {"free", "known"},
                 "Onset fit: `free` = complex amplitude (any phase shift of the path), `known` = the format's sine phases (carrier-resolved; a path's phase shift biases it)."),
      float_param("fit_window_s", 0.003, 0.0005, 0.05, "s", "Onset fit window after the first path."),
      int_param("max_paths", std::int64_t{3}, 1, 3, "",
                "Paths of the multipath onset fit (direct + echoes; 1 = the single-path fit alone)."),
      float_param("path_search_s", 0.0045, 0.0, 0.02, "s",
                  "The first path is searched up to this long before the single-path estimate (floor/ceiling image delays)."),
      float_param("path_window_s", 0.005, 0.0005, 0.02, "s", "Multipath fit window after the single-path estimate."),
      float_param("path_scan_samples", 2.0, 0.5, 16.0, "samples",
                  "Step of the multipath fit's scan for a new path (each found path is then refined to 1/8 sample). "
                  "4 is ~18 % faster, detection as good on the simulator; not the default: one held-out seed's track got worse "
                  "(docs/spyloc.md)."),
      float_param("path_threshold_db", 16.0, 3.0, 40.0, "dB",
                  "A path of the multipath fit must explain this much over the in-band noise power (per sample)."),
      bool_param("doppler", true,
                 "Multipath fit with the beep's time scale (Doppler) measured on its body (tone phase advance)."),
      bool_param("carrier_phase", true,
                 "First path from the carrier phase of its fitted amplitude (the cycle nearest the envelope fit; fit_phase free)."),
      enum_param("cycle_choice", "known_phase", {"known_phase", "envelope"},
                 "With carrier_phase: the carrier cycle of the first path. `envelope` = the cycle nearest the free-phase "
                 "envelope fit; `known_phase` = the cycle (0, ±1, ±2 periods from it) whose fit with the first path at the "
                 "format's own phase, the echoes free, explains most energy (tools/scripts/spyloc_bound.py)."),
      float_param("path_tolerance", 0.02, 0.0, 0.5, "",
                  "... plus this fraction of the window's energy (model mismatch: Doppler, device response)."),
  };
  return schema;
}

const locus_plugin_descriptor* descriptor() {
  static const locus_plugin_descriptor d{
      LOCUS_PLUGIN_ABI_VERSION,
      LOCUS_PLUGIN_DETECTOR,
      "multitone",
      "0.2.0",
      "SpyLoc multitone beeps: tone-bank identity (MAC bits), leading-edge first-path arrival, decay features T5..T30",
      kInputAudio,
      &schema_fn,
      &create,
      nullptr,
  };
  return &d;
}

}  // namespace locus::plugins::multitone
