// How the HAL backends print a number in an error message ("got 44100.5"): the stream's default
// format, six significant digits. One copy for every backend (a unity build compiles them together).
#pragma once

#include <sstream>
#include <string>

namespace locus::hal {

/// [main] `v` as `std::ostream << v` prints it.
inline std::string num(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

}  // namespace locus::hal
