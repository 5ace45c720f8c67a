// TUM link messages: see messages.hpp.
#include "messages.hpp"

#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>
#include "locus/numbers.hpp"

namespace locus::plugins::tum {

namespace {

using json = nlohmann::ordered_json;

json vec(const Vec3a& v) { return json::array({v[0], v[1], v[2]}); }

json times(const std::vector<double>& t) {
  json a = json::array();
  for (double v : t) a.push_back(std::isfinite(v) ? json(v) : json(nullptr));
  return a;
}

bool read_vec(const json& j, Vec3a& out) {
  if (!j.is_array() || j.size() != 3) return false;
  for (std::size_t i = 0; i < 3; ++i) {
    if (!j[i].is_number() || !std::isfinite(j[i].get<double>())) return false;
    out[i] = j[i].get<double>();
  }
  return true;
}

bool read_times(const json& j, std::size_t n, std::vector<double>& out) {
  if (!j.is_array() || j.size() != n) return false;
  out.clear();
  for (const auto& v : j) {
    if (v.is_null()) out.push_back(kNaN);
    else if (v.is_number() && std::isfinite(v.get<double>())) out.push_back(v.get<double>());
    else return false;
  }
  return true;
}

}  // namespace

std::string topic_obs(std::string_view prefix, std::string_view device) {
  return std::string(prefix) + "/obs/" + std::string(device);
}
std::string topic_filter(std::string_view prefix) { return std::string(prefix) + "/#"; }

std::string encode(const ObsMessage& m) {
  json j;
  j["type"] = "tum_obs";
  j["device"] = m.device;
  j["seq"] = m.seq;
  json mics = json::array();
  for (const auto& v : m.mics_m) mics.push_back(vec(v));
  j["mics"] = mics;
  j["speaker"] = m.speaker_m ? vec(*m.speaker_m) : json(nullptr);
  if (m.q_wxyz) j["q_wxyz"] = json::array({(*m.q_wxyz)[0], (*m.q_wxyz)[1], (*m.q_wxyz)[2], (*m.q_wxyz)[3]});
  else j["q_wxyz"] = nullptr;
  j["moving"] = m.moving;
  if (m.gyro_radps) j["w_radps"] = vec(*m.gyro_radps);
  j["t1"] = times(m.t1_s);
  j["t2"] = times(m.t2_s);
  return j.dump(-1, ' ', false, json::error_handler_t::replace);
}

Decoded decode(std::string_view prefix, std::string_view topic, std::string_view payload) {
  Decoded d;
  const std::string head = std::string(prefix) + "/obs/";
  if (topic.substr(0, head.size()) != head || topic.size() == head.size()) {
    d.error = "topic '" + std::string(topic) + "': expected " + head + "<device>";
    return d;
  }
  const std::string topic_device(topic.substr(head.size()));
  json j;
  try {
    j = json::parse(payload);
  } catch (const std::exception& e) {
    d.error = std::string("not JSON: ") + e.what();
    return d;
  }
  if (!j.is_object()) return d.error = "expected a JSON object", d;
  const auto type = j.find("type");
  if (type == j.end() || !type->is_string() || type->get<std::string>() != "tum_obs")
    return d.error = "field 'type': expected \"tum_obs\"", d;
  ObsMessage m;
  const auto dev = j.find("device");
  if (dev == j.end() || !dev->is_string() || dev->get<std::string>().empty())
    return d.error = "field 'device': expected a non-empty string", d;
  m.device = dev->get<std::string>();
  if (m.device != topic_device) return d.error = "field 'device': '" + m.device + "' differs from the topic's '" + topic_device + "'", d;
  const auto seq = j.find("seq");
  if (seq == j.end() || !seq->is_number_unsigned()) return d.error = "field 'seq': expected a non-negative integer", d;
  m.seq = seq->get<std::uint64_t>();
  const auto mics = j.find("mics");
  if (mics == j.end() || !mics->is_array() || mics->size() < 2 || mics->size() > 32)
    return d.error = "field 'mics': expected 2..32 positions [x,y,z]", d;
  for (const auto& v : *mics) {
    Vec3a p{};
    if (!read_vec(v, p)) return d.error = "field 'mics': expected finite [x,y,z] rows", d;
    m.mics_m.push_back(p);
  }
  const auto spk = j.find("speaker");
  if (spk == j.end()) return d.error = "field 'speaker': expected [x,y,z] or null", d;
  if (!spk->is_null()) {
    Vec3a p{};
    if (!read_vec(*spk, p)) return d.error = "field 'speaker': expected [x,y,z] or null", d;
    m.speaker_m = p;
  }
  const auto q = j.find("q_wxyz");
  if (q == j.end()) return d.error = "field 'q_wxyz': expected [w,x,y,z] or null", d;
  if (!q->is_null()) {
    if (!q->is_array() || q->size() != 4) return d.error = "field 'q_wxyz': expected [w,x,y,z] or null", d;
    std::array<double, 4> qq{};
    double n2 = 0.0;
    for (std::size_t i = 0; i < 4; ++i) {
      if (!(*q)[i].is_number() || !std::isfinite((*q)[i].get<double>())) return d.error = "field 'q_wxyz': expected finite numbers", d;
      qq[i] = (*q)[i].get<double>();
      n2 += qq[i] * qq[i];
    }
    if (std::abs(std::sqrt(n2) - 1.0) > 1e-3) return d.error = "field 'q_wxyz': expected a unit quaternion", d;
    m.q_wxyz = qq;
  }
  const auto moving = j.find("moving");
  if (moving == j.end() || !moving->is_boolean()) return d.error = "field 'moving': expected true or false", d;
  m.moving = moving->get<bool>();
  const auto w = j.find("w_radps");
  if (w != j.end() && !w->is_null()) {
    Vec3a g{};
    if (!read_vec(*w, g)) return d.error = "field 'w_radps': expected finite [x,y,z] (rad/s) or null", d;
    m.gyro_radps = g;
  }
  const auto t1 = j.find("t1"), t2 = j.find("t2");
  if (t1 == j.end() || !read_times(*t1, m.mics_m.size(), m.t1_s))
    return d.error = "field 't1': expected one finite time or null per mic", d;
  if (t2 == j.end() || !read_times(*t2, m.mics_m.size(), m.t2_s))
    return d.error = "field 't2': expected one finite time or null per mic", d;
  d.obs = std::move(m);
  return d;
}

}  // namespace locus::plugins::tum
