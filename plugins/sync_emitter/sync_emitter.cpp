// The `sync_emitter` localizer (sync_emitter.hpp): emissions scheduled from radio syncs.
#include "sync_emitter.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace locus::plugins::sync_emitter {

std::int64_t emission_frame(double sync_t_s, double delay_s, double period_s, std::int64_t k, double fs_hz) noexcept {
  return static_cast<std::int64_t>(std::llround((sync_t_s + delay_s + static_cast<double>(k) * period_s) * fs_hz));
}

namespace {

class SyncEmitter final : public Localizer {
 public:
  /// [main]
  void configure(const Params& params, HostContext& ctx) override {
    log_ = &ctx.log;
    device_ = std::string(ctx.device);
    const std::string who = "sync_emitter: ";
    if (device_.empty()) throw std::runtime_error(who + "no device: run it on a node with one device");
    emitter_ = ctx.emitter;
    if (emitter_ == nullptr)
      throw std::runtime_error(who + "device '" + device_ + "' has no emitter: the node needs a `playback:` section "
                               "(a replay has none: the scene already holds what was played)");
    if (ctx.geometry == nullptr || ctx.geometry->emits.empty())
      throw std::runtime_error(who + "device '" + device_ + "' declares no emits: give the node its layout "
                               "(locusd --layout SCENE), whose device or emitter of this id has an acoustic `emits` entry");
    const auto index = params.get_int("emits_index");
    std::vector<std::size_t> acoustic;
    for (std::size_t i = 0; i < ctx.geometry->emits.size(); ++i)
      if (ctx.geometry->emits[i].acoustic()) acoustic.push_back(i);
    if (index < 0) {
      if (acoustic.empty()) throw std::runtime_error(who + "device '" + device_ + "': no acoustic entry in its emits");
      signal_ = ctx.geometry->emits[acoustic.front()];
    } else {
      if (static_cast<std::size_t>(index) >= ctx.geometry->emits.size() || !ctx.geometry->emits[index].acoustic())
        throw std::runtime_error(who + "param 'emits_index': " + std::to_string(index) + " is not an acoustic entry of device '" +
                                 device_ + "' (it has " + std::to_string(ctx.geometry->emits.size()) + " emits entries)");
      signal_ = ctx.geometry->emits[index];
    }
    delay_s_ = params.get_float("delay_s");
    if (delay_s_ < 0.0) {
      if (!signal_.sync_delay_s)
        throw std::runtime_error(who + "device '" + device_ + "': its " + signal_.type +
                                 " signal has no sync_delay_s and param 'delay_s' is not given (expected the delay from sync to sound, s)");
      delay_s_ = *signal_.sync_delay_s;
    }
    period_s_ = params.get_float("repeat_period_s");
    count_ = params.get_int("repeat_count");
    if (count_ > 1 && !(period_s_ > 0.0))
      throw std::runtime_error(who + "param 'repeat_period_s': expected > 0 s with repeat_count " + std::to_string(count_));
    gain_ = params.get_float("gain");
    const std::string list = params.get_string("sources");
    if (list.empty()) {
      sources_ = {device_};
    } else {
      std::stringstream ss(list);
      for (std::string item; std::getline(ss, item, ',');)
        if (!item.empty()) sources_.push_back(item);
    }
    fs_ = emitter_->sample_rate_hz();
    ctx.log.info(who + device_ + ": " + signal_.type + " " + std::to_string(delay_s_) + " s after each sync from " + list_of(sources_) +
                 (count_ > 1 ? ", " + std::to_string(count_) + " times every " + std::to_string(period_s_) + " s" : ""));
  }

  /// [main]
  std::vector<EventType> subscriptions() const override { return {EventType::RadioSync}; }

  /// [main]
  void on_event(const Event& event, Publisher& /*out*/) override {
    const auto* s = std::get_if<RadioSync>(&event);
    if (s == nullptr || s->device.view() != device_) return;
    if (std::find(sources_.begin(), sources_.end(), s->source.view()) == sources_.end()) return;
    ++syncs_;
    for (std::int64_t k = 0; k < count_; ++k) {
      const std::int64_t frame = emission_frame(s->t_s, delay_s_, period_s_, k, fs_);
      const auto now = static_cast<std::int64_t>(emitter_->playback_frame());
      if (frame < now) {  // the playback stream is past it: the sync came too late for this one
        ++late_;
        continue;
      }
      std::string err;
      if (!emitter_->schedule(signal_, static_cast<std::uint64_t>(frame), gain_, &err)) {
        if (refused_++ == 0) first_error_ = err;
        continue;
      }
      ++scheduled_;
      leads_ms_.push_back(static_cast<double>(frame - now) / fs_ * 1e3);
    }
  }

  /// [main]
  void finish(Publisher& /*out*/) override {
    std::string lead = "none scheduled";
    if (!leads_ms_.empty()) {
      std::vector<double> v = leads_ms_;
      std::sort(v.begin(), v.end());
      char buf[96];
      std::snprintf(buf, sizeof buf, "lead min %.1f ms, median %.1f ms", v.front(), v[v.size() / 2]);
      lead = buf;
    }
    log_->info("sync_emitter " + device_ + ": " + std::to_string(syncs_) + " syncs, " + std::to_string(scheduled_) +
               " emissions scheduled, " + std::to_string(late_) + " late (not scheduled), " + std::to_string(refused_) +
               " refused, " + std::to_string(emitter_->late_emissions()) + " cut by the emitter; " + lead);
    if (refused_ > 0) log_->warn("sync_emitter " + device_ + ": first refusal: " + first_error_);
  }

 private:
  static std::string list_of(const std::vector<std::string>& v) {
    std::string out;
    for (const auto& s : v) out += (out.empty() ? "" : ",") + s;
    return out;
  }

  Logger* log_ = nullptr;
  Emitter* emitter_ = nullptr;
  std::string device_;
  SignalSpec signal_;
  std::vector<std::string> sources_;
  double delay_s_ = 0.0, period_s_ = 0.0, gain_ = 1.0, fs_ = 44100.0;
  std::int64_t count_ = 1;
  std::uint64_t syncs_ = 0, scheduled_ = 0, late_ = 0, refused_ = 0;
  std::string first_error_;
  std::vector<double> leads_ms_;
};

}  // namespace

const ParamSchema& schema() {
  static const ParamSchema s = {
      string_param("sources", std::string(""),
                   "Senders whose syncs trigger an emission, comma-separated ids; \"\" = the device itself (a beacon)."),
      int_param("emits_index", std::int64_t{-1}, -1, 63, "", "Which `emits` entry of the device is played; -1 = its first acoustic one."),
      float_param("delay_s", -1.0, -1.0, 3600.0, "s", "Sync-to-sound delay; -1 = the signal's sync_delay_s."),
      float_param("repeat_period_s", 0.0, 0.0, 3600.0, "s", "Emissions after one sync are this far apart (Montage's rounds)."),
      int_param("repeat_count", std::int64_t{1}, 1, 48, "", "Emissions per sync (the playback queue holds 64)."),
      float_param("gain", 1.0, 0.0, 1.0, "", "Gain of the scheduled signal (its own amplitude applies too)."),
  };
  return s;
}

const locus_plugin_descriptor* descriptor() {
  static const locus_plugin_descriptor d{
      LOCUS_PLUGIN_ABI_VERSION, LOCUS_PLUGIN_LOCALIZER, "sync_emitter", "1",
      "Live emitting role: plays the device's signal a known delay after each radio sync (SpyLoc beacons, Montage walkers)", 0,
      [] { return &schema(); }, nullptr, [] { return static_cast<Localizer*>(new SyncEmitter); }};
  return &d;
}

}  // namespace locus::plugins::sync_emitter
