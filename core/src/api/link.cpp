#include "locus/link.hpp"

namespace locus {

// MQTT 3.1.1 section 4.7 semantics: levels split on '/', '+' matches exactly one level (possibly
// empty), a trailing '#' matches the parent level and everything below it.
bool topic_matches(std::string_view filter, std::string_view topic) noexcept {
  std::size_t f = 0, t = 0;
  for (;;) {
    const std::size_t f_end = filter.find('/', f);
    const std::string_view f_level = filter.substr(f, f_end == std::string_view::npos ? std::string_view::npos : f_end - f);
    if (f_level == "#") return f_end == std::string_view::npos;
    if (t > topic.size()) return false;  // topic exhausted but filter has more levels
    const std::size_t t_end = topic.find('/', t);
    const std::string_view t_level = topic.substr(t, t_end == std::string_view::npos ? std::string_view::npos : t_end - t);
    if (f_level != "+" && f_level != t_level) return false;
    const bool f_last = f_end == std::string_view::npos;
    const bool t_last = t_end == std::string_view::npos;
    if (f_last || t_last) {
      if (f_last && t_last) return true;
      // "a/#" also matches "a": filter continues with exactly "#"
      return t_last && !f_last && filter.substr(f_end + 1) == "#";
    }
    f = f_end + 1;
    t = t_end + 1;
  }
}

}  // namespace locus
