#include "locus/json_events.hpp"

#include <cerrno>
#include <cmath>
#include <cstring>
#include <stdexcept>

namespace locus {

namespace {

nlohmann::ordered_json num(double v) { return std::isfinite(v) ? nlohmann::ordered_json(v) : nlohmann::ordered_json(nullptr); }

template <std::size_t N>
nlohmann::ordered_json vec(const std::array<float, N>& a) {
  nlohmann::ordered_json j = nlohmann::ordered_json::array();
  for (float v : a) j.push_back(num(v));
  return j;
}

std::string mac(const std::array<std::uint8_t, 6>& a) {
  char buf[18];
  std::snprintf(buf, sizeof buf, "%02X:%02X:%02X:%02X:%02X:%02X", a[0], a[1], a[2], a[3], a[4], a[5]);
  return buf;
}

struct ToJson {
  nlohmann::ordered_json& j;
  void operator()(const AudioDetection& e) const {
    j["device"] = e.device.str();
    j["detector"] = e.detector.str();
    j["stream"] = e.stream;
    j["channel"] = e.channel;
    j["template"] = e.template_index;
    j["frame"] = e.frame;
    j["t_s"] = e.sample_rate_hz > 0 ? num(e.frame / e.sample_rate_hz) : nlohmann::ordered_json(nullptr);
    j["sample_rate_hz"] = e.sample_rate_hz;
    j["snr_db"] = num(e.snr_db);
    j["confidence"] = num(e.confidence);
    j["amplitude"] = num(e.amplitude);
    if (e.carrier_period > 0.0f) {
      j["envelope_frame"] = e.envelope_frame;
      j["carrier_period"] = num(e.carrier_period);
    }
  }
  void operator()(const ImuSample& e) const {
    j["device"] = e.device.str();
    j["t_s"] = e.t_s;
    j["accel_mps2"] = vec(e.accel_mps2);
    j["gyro_radps"] = vec(e.gyro_radps);
    j["mag_ut"] = e.has_mag ? vec(e.mag_ut) : nlohmann::ordered_json(nullptr);
  }
  void operator()(const BleAdvertisement& e) const {
    j["device"] = e.device.str();
    j["t_s"] = e.t_s;
    j["address"] = mac(e.address);
    j["rssi_dbm"] = num(e.rssi_dbm);
    j["tx_power_dbm"] = e.has_tx_power ? num(e.tx_power_dbm) : nlohmann::ordered_json(nullptr);
    j["channel"] = e.channel == 0 ? nlohmann::ordered_json(nullptr) : nlohmann::ordered_json(e.channel);
  }
  void operator()(const RadioSync& e) const {
    j["device"] = e.device.str();
    j["t_s"] = e.t_s;
    j["source"] = e.source.str();
  }
  void operator()(const Step& e) const {
    j["device"] = e.device.str();
    j["detector"] = e.detector.str();
    j["t_s"] = e.t_s;
    j["stride_m"] = num(e.stride_m);
    j["frequency_hz"] = num(e.frequency_hz);
  }
  void operator()(const Attitude& e) const {
    j["device"] = e.device.str();
    j["detector"] = e.detector.str();
    j["t_s"] = e.t_s;
    j["q_wxyz"] = vec(e.q_wxyz);
    j["heading_rad"] = num(e.heading_rad);
  }
  void operator()(const DecayFeatures& e) const {
    j["device"] = e.device.str();
    j["detector"] = e.detector.str();
    j["stream"] = e.stream;
    j["channel"] = e.channel;
    j["template"] = e.template_index;
    j["frame"] = e.frame;
    j["t_s"] = e.sample_rate_hz > 0 ? num(e.frame / e.sample_rate_hz) : nlohmann::ordered_json(nullptr);
    j["decay_s"] = vec(e.decay_s);
    j["noise_margin_db"] = num(e.noise_margin_db);
  }
  void operator()(const Estimate& e) const {
    j["plugin"] = e.plugin.str();
    j["reference"] = e.reference.str();
    j["frame"] = e.frame.str();
    j["target"] = e.target.str();
    j["t_s"] = e.t_s;
    nlohmann::ordered_json p = nlohmann::ordered_json::array();
    for (int i = 0; i < e.dims && i < 3; ++i) p.push_back(num(e.position_m[static_cast<std::size_t>(i)]));
    j["position_m"] = p;
    j["direction_rad"] = num(e.direction_rad);
    j["distance_m"] = num(e.distance_m);
    j["std_m"] = num(e.std_m);
    j["confidence"] = num(e.confidence);
    j["direction_std_rad"] = num(e.direction_std_rad);
    j["distance_std_m"] = num(e.distance_std_m);
    nlohmann::ordered_json flags = nlohmann::ordered_json::array();
    if (e.flags & kEstimateDirectionOnly) flags.push_back("direction_only");
    if (e.flags & kEstimateAmbiguous) flags.push_back("ambiguous");
    if (e.flags & kEstimateInconsistent) flags.push_back("inconsistent");
    if (e.flags & kEstimateWeak) flags.push_back("weak");
    if (e.flags & kEstimateHeightUnobserved) flags.push_back("height_unobserved");
    j["flags"] = flags;
    if (e.los >= 0) j["los"] = e.los == 1;
  }
};

}  // namespace

nlohmann::ordered_json event_to_json(const Event& event) {
  nlohmann::ordered_json j = nlohmann::ordered_json::object();
  j["type"] = std::string(event_type_name(type_of(event)));
  std::visit(ToJson{j}, event);
  return j;
}

JsonLinesWriter::JsonLinesWriter(const std::string& path, ProblemHandler on_problem)
    : path_(path), on_problem_(std::move(on_problem)) {
  if (path == "-") {
    file_ = stdout;
  } else {
    file_ = std::fopen(path.c_str(), "w");
    if (!file_) throw std::runtime_error("cannot open output '" + path + "': " + std::strerror(errno));
    owned_ = true;
  }
}

JsonLinesWriter::~JsonLinesWriter() {
  flush();
  if (owned_) std::fclose(file_);
}

void JsonLinesWriter::write(const Event& event) { write(event_to_json(event)); }

void JsonLinesWriter::write(const nlohmann::ordered_json& object) {
  const std::string line = object.dump(-1, ' ', false, nlohmann::ordered_json::error_handler_t::replace) + "\n";
  errno = 0;
  const bool ok = std::fwrite(line.data(), 1, line.size(), file_) == line.size() && std::fflush(file_) == 0;
  if (ok) {
    ++lines_;
    if (failing_run_ > 0 && on_problem_) {
      on_problem_("output '" + path_ + "': writing again after " + std::to_string(failing_run_) + " lines not written",
                  false);
    }
    failing_run_ = 0;
    return;
  }
  const int err = errno;
  std::clearerr(file_);
  ++lines_failed_;
  if (failing_run_++ == 0) {
    error_ = err != 0 ? std::strerror(err) : "write error";
    if (on_problem_) {
      on_problem_("output '" + path_ + "': write failed (" + error_ + ") after " + std::to_string(lines_) +
                      " lines; the node goes on, lines that cannot be written are counted",
                  true);
    }
  }
}

void JsonLinesWriter::flush() {
  if (file_) std::fflush(file_);
}

}  // namespace locus
