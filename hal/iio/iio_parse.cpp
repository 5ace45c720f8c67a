// IIO sysfs parsers and scan layout (see iio_parse.hpp for the conventions and why they are ours).
#include "iio/iio_parse.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <system_error>

namespace locus::hal::iio {

namespace {

constexpr const char* kTypeGrammar = "expected [be|le]:[s|u]<bits>/<storagebits>[X<repeat>][>><shift>]";

[[noreturn]] void type_error(std::string_view text, const std::string& what) {
  throw IioError("scan element type '" + std::string(text) + "': " + what + "; " + kTypeGrammar);
}

/// Reads decimal digits at `pos` into `out`; false when there are none or it overflows.
bool take_uint(std::string_view s, std::size_t& pos, unsigned& out) {
  const char* first = s.data() + pos;
  const char* last = s.data() + s.size();
  if (first == last || *first < '0' || *first > '9') return false;
  const auto r = std::from_chars(first, last, out, 10);
  if (r.ec != std::errc()) return false;
  pos += static_cast<std::size_t>(r.ptr - first);
  return true;
}

std::string errno_text(int err) { return std::strerror(err); }

}  // namespace

std::string_view trim_sysfs(std::string_view text) noexcept {
  auto blank = [](char c) { return c == '\n' || c == '\0' || c == '\r' || c == ' ' || c == '\t'; };
  while (!text.empty() && blank(text.back())) text.remove_suffix(1);
  while (!text.empty() && blank(text.front())) text.remove_prefix(1);
  return text;
}

ScanType parse_scan_type(std::string_view raw) {
  const std::string_view s = trim_sysfs(raw);
  if (s.empty()) type_error(raw, "empty");
  ScanType t;
  std::size_t pos = 0;
  if (s.substr(0, 3) == "le:") {
    t.big_endian = false;
  } else if (s.substr(0, 3) == "be:") {
    t.big_endian = true;
  } else {
    type_error(s, "unknown endianness '" + std::string(s.substr(0, s.find(':'))) + "' (le or be)");
  }
  pos = 3;
  if (pos >= s.size() || (s[pos] != 's' && s[pos] != 'u')) {
    type_error(s, "sign must be 's' or 'u' after the ':'");
  }
  t.is_signed = s[pos] == 's';
  ++pos;
  if (!take_uint(s, pos, t.bits)) type_error(s, "missing or bad <bits>");
  if (pos >= s.size() || s[pos] != '/') type_error(s, "missing '/' after <bits>");
  ++pos;
  if (!take_uint(s, pos, t.storage_bits)) type_error(s, "missing or bad <storagebits>");
  if (pos < s.size() && s[pos] == 'X') {
    ++pos;
    if (!take_uint(s, pos, t.repeat)) type_error(s, "missing or bad <repeat> after 'X'");
  }
  if (pos < s.size()) {
    if (s.substr(pos, 2) != ">>") type_error(s, "unexpected '" + std::string(s.substr(pos)) + "'");
    pos += 2;
    if (!take_uint(s, pos, t.shift)) type_error(s, "missing or bad <shift> after '>>'");
    if (pos != s.size()) type_error(s, "unexpected '" + std::string(s.substr(pos)) + "' after the shift");
  }
  if (t.storage_bits != 8 && t.storage_bits != 16 && t.storage_bits != 32 && t.storage_bits != 64) {
    type_error(s, "storagebits " + std::to_string(t.storage_bits) + " is not 8, 16, 32 or 64");
  }
  if (t.bits == 0 || t.bits > t.storage_bits) {
    type_error(s, "bits " + std::to_string(t.bits) + " must be 1.." + std::to_string(t.storage_bits) +
                      " (the storage size)");
  }
  if (t.shift >= t.storage_bits || t.shift + t.bits > t.storage_bits) {
    type_error(s, "shift " + std::to_string(t.shift) + " + bits " + std::to_string(t.bits) +
                      " exceeds storagebits " + std::to_string(t.storage_bits));
  }
  if (t.repeat == 0 || t.repeat > 1024) type_error(s, "repeat " + std::to_string(t.repeat) + " must be 1..1024");
  return t;
}

std::string format_scan_type(const ScanType& t) {
  std::string out = t.big_endian ? "be:" : "le:";
  out += t.is_signed ? 's' : 'u';
  out += std::to_string(t.bits) + "/" + std::to_string(t.storage_bits);
  if (t.repeat > 1) out += "X" + std::to_string(t.repeat);
  out += ">>" + std::to_string(t.shift);
  return out;
}

double parse_sysfs_double(std::string_view raw, std::string_view what) {
  const std::string_view s = trim_sysfs(raw);
  auto bad = [&](const std::string& why) -> IioError {
    return IioError(std::string(what) + ": '" + std::string(s) + "' " + why + " (expected a decimal number such as 0.000598550)");
  };
  if (s.empty()) throw bad("is empty");
  const char* first = s.data();
  const char* last = s.data() + s.size();
  if (*first == '+') ++first;  // from_chars takes no leading '+'
  double v = 0.0;
  const auto r = std::from_chars(first, last, v, std::chars_format::general);
  if (r.ec == std::errc::result_out_of_range) throw bad("is out of range");
  if (r.ec != std::errc() || r.ptr == first) throw bad("is not a number");
  if (r.ptr != last) throw bad("has trailing characters '" + std::string(r.ptr, last) + "'");
  if (!std::isfinite(v)) throw bad("is not finite");
  return v;
}

std::int64_t parse_sysfs_int(std::string_view raw, std::string_view what) {
  const std::string_view s = trim_sysfs(raw);
  auto bad = [&](const std::string& why) -> IioError {
    return IioError(std::string(what) + ": '" + std::string(s) + "' " + why + " (expected an integer)");
  };
  if (s.empty()) throw bad("is empty");
  const char* first = s.data();
  const char* last = s.data() + s.size();
  if (*first == '+') ++first;
  std::int64_t v = 0;
  const auto r = std::from_chars(first, last, v, 10);
  if (r.ec == std::errc::result_out_of_range) throw bad("is out of range");
  if (r.ec != std::errc() || r.ptr == first) throw bad("is not an integer");
  if (r.ptr != last) throw bad("has trailing characters '" + std::string(r.ptr, last) + "'");
  return v;
}

Matrix3 parse_mount_matrix(std::string_view raw, std::string_view what) {
  const std::string_view s = trim_sysfs(raw);
  Matrix3 m{};
  std::size_t row = 0;
  std::size_t start = 0;
  for (;;) {
    const std::size_t end = std::min(s.find(';', start), s.size());
    if (row >= 3) {
      throw IioError(std::string(what) + ": mount matrix '" + std::string(s) +
                     "' has more than 3 rows (expected 'x1, y1, z1; x2, y2, z2; x3, y3, z3')");
    }
    std::string_view r = s.substr(start, end - start);
    std::size_t col = 0;
    std::size_t cs = 0;
    for (;;) {
      const std::size_t ce = std::min(r.find(',', cs), r.size());
      if (col >= 3) {
        throw IioError(std::string(what) + ": mount matrix row " + std::to_string(row + 1) +
                       " has more than 3 values (expected 'x1, y1, z1; x2, y2, z2; x3, y3, z3')");
      }
      m[row][col++] = parse_sysfs_double(trim_sysfs(r.substr(cs, ce - cs)), what);
      if (ce >= r.size()) break;
      cs = ce + 1;
    }
    if (col != 3) {
      throw IioError(std::string(what) + ": mount matrix row " + std::to_string(row + 1) + " has " +
                     std::to_string(col) + " values (expected 3: 'x1, y1, z1; x2, y2, z2; x3, y3, z3')");
    }
    ++row;
    if (end >= s.size()) break;
    start = end + 1;
  }
  if (row != 3) {
    throw IioError(std::string(what) + ": mount matrix '" + std::string(s) + "' has " + std::to_string(row) +
                   " rows (expected 3: 'x1, y1, z1; x2, y2, z2; x3, y3, z3')");
  }
  return m;
}

// ------------------------------------------------------------------ files

bool read_sysfs_optional(const std::string& path, std::string& out) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    const int err = errno;
    if (err == ENOENT) return false;
    throw IioError("cannot read " + path + ": " + errno_text(err));
  }
  std::string text;
  char buf[4096];
  for (;;) {
    const ssize_t n = ::read(fd, buf, sizeof buf);
    if (n < 0) {
      if (errno == EINTR) continue;
      const int err = errno;
      ::close(fd);
      throw IioError("cannot read " + path + ": " + errno_text(err));
    }
    if (n == 0) break;
    text.append(buf, static_cast<std::size_t>(n));
    if (text.size() > (1u << 20)) {
      ::close(fd);
      throw IioError("cannot read " + path + ": more than 1 MiB (not a sysfs attribute)");
    }
  }
  ::close(fd);
  out = std::string(trim_sysfs(text));
  return true;
}

std::string read_sysfs(const std::string& path) {
  std::string out;
  if (!read_sysfs_optional(path, out)) throw IioError("cannot read " + path + ": " + errno_text(ENOENT));
  return out;
}

void write_sysfs(const std::string& path, std::string_view value) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_TRUNC | O_CLOEXEC);
  if (fd < 0) {
    const int err = errno;
    throw IioError("cannot write '" + std::string(value) + "' to " + path + ": " + errno_text(err));
  }
  std::string text(value);
  text += '\n';
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      const int err = errno;
      ::close(fd);
      throw IioError("cannot write '" + std::string(value) + "' to " + path + ": " + errno_text(err));
    }
    done += static_cast<std::size_t>(n);
  }
  if (::close(fd) != 0) {
    const int err = errno;
    throw IioError("cannot write '" + std::string(value) + "' to " + path + ": " + errno_text(err));
  }
}

double read_sysfs_double(const std::string& path) { return parse_sysfs_double(read_sysfs(path), path); }
std::int64_t read_sysfs_int(const std::string& path) { return parse_sysfs_int(read_sysfs(path), path); }

// ------------------------------------------------------------------ channels and layout

std::vector<ScanChannel> discover_scan_elements(const std::string& dir) {
  namespace fs = std::filesystem;
  std::vector<ScanChannel> out;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return out;
  std::vector<std::string> names;
  for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string file = it->path().filename().string();
    if (file.size() > 3 && file.compare(file.size() - 3, 3, "_en") == 0) names.push_back(file.substr(0, file.size() - 3));
  }
  if (ec) throw IioError("cannot list " + dir + ": " + ec.message());
  std::sort(names.begin(), names.end());
  for (const std::string& name : names) {
    ScanChannel ch;
    ch.name = name;
    const std::string base = dir + "/" + name;
    const std::int64_t en = read_sysfs_int(base + "_en");
    if (en != 0 && en != 1) throw IioError(base + "_en: '" + std::to_string(en) + "' (expected 0 or 1)");
    ch.enabled = en == 1;
    std::string text;
    if (!read_sysfs_optional(base + "_index", text)) {
      throw IioError(base + "_index: missing (every scan element needs _en, _index and _type)");
    }
    ch.index = parse_sysfs_int(text, base + "_index");
    if (ch.index < 0) throw IioError(base + "_index: " + std::to_string(ch.index) + " (expected >= 0)");
    if (!read_sysfs_optional(base + "_type", text)) {
      throw IioError(base + "_type: missing (every scan element needs _en, _index and _type)");
    }
    try {
      ch.type = parse_scan_type(text);
    } catch (const IioError& e) {
      throw IioError(base + "_type: " + e.what());
    }
    out.push_back(std::move(ch));
  }
  std::stable_sort(out.begin(), out.end(), [](const ScanChannel& a, const ScanChannel& b) { return a.index < b.index; });
  for (std::size_t i = 1; i < out.size(); ++i) {
    if (out[i].index == out[i - 1].index) {
      throw IioError(dir + ": channels " + out[i - 1].name + " and " + out[i].name + " share scan index " +
                     std::to_string(out[i].index) + " (indices must be unique)");
    }
  }
  return out;
}

const ScanSlot* ScanLayout::find(std::string_view name) const noexcept {
  for (const ScanSlot& s : slots) {
    if (s.name == name) return &s;
  }
  return nullptr;
}

ScanLayout compute_layout(const std::vector<ScanChannel>& channels) {
  std::vector<const ScanChannel*> enabled;
  for (const ScanChannel& c : channels) {
    if (c.enabled) enabled.push_back(&c);
  }
  if (enabled.empty()) throw IioError("scan layout: no scan element is enabled");
  std::stable_sort(enabled.begin(), enabled.end(),
                   [](const ScanChannel* a, const ScanChannel* b) { return a->index < b->index; });
  ScanLayout layout;
  std::size_t bytes = 0;
  std::size_t largest = 1;
  for (std::size_t i = 0; i < enabled.size(); ++i) {
    const ScanChannel& c = *enabled[i];
    if (i > 0 && c.index == enabled[i - 1]->index) {
      throw IioError("scan layout: channels " + enabled[i - 1]->name + " and " + c.name + " share scan index " +
                     std::to_string(c.index));
    }
    const std::size_t len = c.type.storage_bytes();
    largest = std::max(largest, len);
    if (bytes % len != 0) bytes += len - bytes % len;
    layout.slots.push_back(ScanSlot{c.name, c.index, c.type, bytes});
    bytes += len;
  }
  if (bytes % largest != 0) bytes += largest - bytes % largest;
  layout.scan_bytes = bytes;
  return layout;
}

std::int64_t unpack_value(const std::uint8_t* scan, std::size_t offset, const ScanType& t, unsigned element) noexcept {
  const std::size_t n = t.element_bytes();
  const std::uint8_t* p = scan + offset + static_cast<std::size_t>(element) * n;
  std::uint64_t word = 0;
  if (t.big_endian) {
    for (std::size_t i = 0; i < n; ++i) word = (word << 8) | p[i];
  } else {
    for (std::size_t i = n; i-- > 0;) word = (word << 8) | p[i];
  }
  word >>= t.shift;
  if (t.bits < 64) {
    const std::uint64_t mask = (std::uint64_t{1} << t.bits) - 1;
    word &= mask;
    if (t.is_signed && (word >> (t.bits - 1)) != 0) word |= ~mask;  // sign-extend
  }
  return static_cast<std::int64_t>(word);
}

void pack_value(std::uint8_t* scan, std::size_t offset, const ScanType& t, std::int64_t value, unsigned element) noexcept {
  const std::size_t n = t.element_bytes();
  std::uint8_t* p = scan + offset + static_cast<std::size_t>(element) * n;
  std::uint64_t word = static_cast<std::uint64_t>(value);
  if (t.bits < 64) word &= (std::uint64_t{1} << t.bits) - 1;
  word <<= t.shift;
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint8_t byte = static_cast<std::uint8_t>(word >> (8 * i));
    if (t.big_endian) {
      p[n - 1 - i] = byte;
    } else {
      p[i] = byte;
    }
  }
}

}  // namespace locus::hal::iio
