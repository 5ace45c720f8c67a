// PlaybackScheduler and SchedulerEmitter (see playback.hpp). The RT side owns `active_` and the clip
// objects it took from `incoming_` until it hands them back through `finished_`; the main side owns
// allocation and freeing. `outstanding_` bounds the clips in flight so that `finished_` can never be
// full when the RT side pushes into it.
#include "locus/playback.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

#include "locus/dsp/signals.hpp"

namespace locus {

namespace {
std::uint32_t round_up_pow2(std::uint32_t n) {
  std::uint32_t p = 1;
  while (p < n) p <<= 1;
  return p;
}
}  // namespace

PlaybackScheduler::PlaybackScheduler(double sample_rate_hz, std::uint32_t max_pending)
    : sample_rate_hz_(sample_rate_hz),
      max_pending_(round_up_pow2(std::max<std::uint32_t>(max_pending, 1))),
      incoming_(max_pending_),
      finished_(max_pending_) {
  if (!(sample_rate_hz > 0.0)) throw std::invalid_argument("playback: sample rate must be > 0");
  active_.assign(max_pending_, nullptr);
}

PlaybackScheduler::~PlaybackScheduler() {
  // The sink is stopped before the scheduler dies (AudioSink::stop contract): every clip is ours now.
  Clip* c = nullptr;
  while (incoming_.try_pop(c)) delete c;
  while (finished_.try_pop(c)) delete c;
  for (std::size_t i = 0; i < active_count_; ++i) delete active_[i];
}

bool PlaybackScheduler::submit(std::vector<float> samples, std::uint64_t start_frame) {
  reclaim();
  if (outstanding_.load(std::memory_order_acquire) >= max_pending_) return false;
  auto* clip = new Clip{std::move(samples), start_frame, false};  // cut = false
  if (!incoming_.try_push(clip)) {  // cannot happen while outstanding_ < capacity; stay safe
    delete clip;
    return false;
  }
  outstanding_.fetch_add(1, std::memory_order_acq_rel);
  return true;
}

std::size_t PlaybackScheduler::reclaim() {
  std::size_t n = 0;
  Clip* c = nullptr;
  while (finished_.try_pop(c)) {
    delete c;
    ++n;
  }
  if (n > 0) outstanding_.fetch_sub(static_cast<std::uint32_t>(n), std::memory_order_acq_rel);
  return n;
}

void PlaybackScheduler::take_new_clips() noexcept {
  Clip* c = nullptr;
  const std::uint64_t now = frame_.load(std::memory_order_relaxed);
  while (active_count_ < active_.size() && incoming_.try_pop(c)) {
    if (c->start_frame < now) {
      c->cut = true;  // its beginning was due before the RT side saw it: cut
      late_.fetch_add(1, std::memory_order_relaxed);
    }
    active_[active_count_++] = c;
  }
}

template <typename Write>
void PlaybackScheduler::render_common(std::uint32_t frames, Write&& write) noexcept {
  take_new_clips();
  const std::uint64_t first = frame_.load(std::memory_order_relaxed);
  const std::uint64_t end = first + frames;
  std::size_t i = 0;
  while (i < active_count_) {
    Clip* c = active_[i];
    const std::uint64_t c_end = c->start_frame + c->samples.size();
    if (c->start_frame < end && c_end > first) {
      const std::uint64_t from = std::max(first, c->start_frame);
      const std::uint64_t to = std::min(end, c_end);
      for (std::uint64_t f = from; f < to; ++f) {
        write(static_cast<std::uint32_t>(f - first), c->samples[static_cast<std::size_t>(f - c->start_frame)]);
      }
    }
    if (c_end <= end) {
      // Done: hand back to the main side (finished_ has room for every outstanding clip).
      if (c_end > first || c->samples.empty()) played_.fetch_add(1, std::memory_order_relaxed);
      finished_.try_push(c);
      active_[i] = active_[--active_count_];
      continue;
    }
    ++i;
  }
  frame_.store(end, std::memory_order_release);
}

void PlaybackScheduler::render_interleaved(float* out, std::uint32_t frames, std::uint32_t channels) noexcept {
  std::fill(out, out + static_cast<std::size_t>(frames) * channels, 0.0f);
  render_common(frames, [&](std::uint32_t f, float v) {
    float* row = out + static_cast<std::size_t>(f) * channels;
    for (std::uint32_t ch = 0; ch < channels; ++ch) row[ch] += v;
  });
}

void PlaybackScheduler::render_planar(float* const* out, std::uint32_t frames, std::uint32_t channels) noexcept {
  for (std::uint32_t ch = 0; ch < channels; ++ch) {
    if (out[ch] != nullptr) std::fill(out[ch], out[ch] + frames, 0.0f);
  }
  render_common(frames, [&](std::uint32_t f, float v) {
    for (std::uint32_t ch = 0; ch < channels; ++ch) {
      if (out[ch] != nullptr) out[ch][f] += v;
    }
  });
}

void PlaybackScheduler::skip(std::uint64_t frames) noexcept {
  take_new_clips();
  const std::uint64_t first = frame_.load(std::memory_order_relaxed);
  const std::uint64_t end = first + frames;
  std::size_t i = 0;
  while (i < active_count_) {
    Clip* c = active_[i];
    const std::uint64_t c_end = c->start_frame + c->samples.size();
    const bool overlaps = c->start_frame < end && c_end > first;
    if (overlaps && !c->cut) {
      c->cut = true;  // part of it falls into the lost span
      late_.fetch_add(1, std::memory_order_relaxed);
    }
    if (c_end <= end) {
      finished_.try_push(c);
      active_[i] = active_[--active_count_];
      continue;
    }
    ++i;
  }
  frame_.store(end, std::memory_order_release);
}

bool SchedulerEmitter::schedule(const SignalSpec& spec, std::uint64_t start_frame, double gain, std::string* error) {
  auto fail = [&](std::string msg) {
    ++refused_;
    if (error != nullptr) *error = std::move(msg);
    return false;
  };
  if (!(gain >= 0.0 && gain <= 1.0)) return fail("emitter: gain must be in 0..1");
  if (const std::vector<SignalIssue> issues = check_signal(spec); !issues.empty()) {
    std::string msg = "emitter: invalid signal";
    for (const SignalIssue& is : issues) msg += (&is == &issues.front() ? ": " : "; ") + is.field + ": " + is.message;
    return fail(std::move(msg));
  }
  if (!spec.acoustic()) return fail("emitter: signal type '" + spec.type + "' is not acoustic (lfm, gold, multitone)");
  if (start_frame < scheduler_.frame()) {
    return fail("emitter: start frame " + std::to_string(start_frame) + " has already been played (playback is at " +
                std::to_string(scheduler_.frame()) + ")");
  }
  std::vector<float> samples;
  try {
    samples = dsp::render_signal(spec, scheduler_.sample_rate_hz());
  } catch (const std::exception& e) {
    return fail(std::string("emitter: cannot render the signal: ") + e.what());
  }
  for (float& v : samples) v = static_cast<float>(v * gain);
  if (!scheduler_.submit(std::move(samples), start_frame)) return fail("emitter: too many emissions pending");
  return true;
}

}  // namespace locus
