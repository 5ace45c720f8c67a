// Parsers for the Linux IIO sysfs ABI (Documentation/ABI/testing/sysfs-bus-iio and
// driver-api/iio/buffers): scan element type strings, sysfs values, scale/offset, mount matrices,
// channel discovery in scan_elements/, the packed layout of one scan and unpacking a scan into values.
//
// Why our own and not libiio: libiio's local backend has the sysfs and /dev paths hard-coded, so it
// cannot be pointed at a fake tree without a mount namespace; the format itself is small and stable.
// Everything here is strict: a malformed type string, a garbage number or a channel with a missing
// _index/_type file is an error naming the file and what was expected, never a silent default.
//
// Kernel conventions implemented (industrialio-buffer.c):
//   type      "[be|le]:[s|u]<bits>/<storagebits>[X<repeat>][>><shift>]", storagebits in {8,16,32,64}
//   value     v = (storage >> shift) & mask(bits), sign-extended when 's'
//   scaled    (v + offset) * scale
//   layout    enabled channels in scan-index order, each aligned to its own storage size
//             (storagebits/8 * repeat), the scan padded to a multiple of the largest storage size.
//
// [main] for everything that touches files; unpack_value()/ScanLayout access are [RT]-safe (no
// allocation, no locks).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace locus::hal::iio {

/// A malformed sysfs value, type string, tree or layout. what() names the file (when known) and what
/// was expected.
class IioError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// One parsed scan element type.
struct ScanType {
  bool big_endian = false;
  bool is_signed = false;
  unsigned bits = 0;          ///< valid bits (1..storage_bits)
  unsigned storage_bits = 0;  ///< 8, 16, 32 or 64
  unsigned repeat = 1;        ///< number of elements of this channel in one scan
  unsigned shift = 0;         ///< right shift before masking (shift + bits <= storage_bits)

  /// Bytes of one element.
  std::size_t element_bytes() const noexcept { return storage_bits / 8; }
  /// Bytes of the whole channel in a scan (also its alignment).
  std::size_t storage_bytes() const noexcept { return element_bytes() * repeat; }
  bool operator==(const ScanType&) const = default;
};

/// Parses a scan element type ("le:s16/16>>0", "be:u12/16>>4", "le:s16/16X3>>0"); ">>shift" may be
/// omitted (0). Trailing newline/NUL/blanks are tolerated. Throws IioError("scan element type '...':
/// <what is wrong>; expected [be|le]:[s|u]bits/storagebits[Xrepeat][>>shift]").
ScanType parse_scan_type(std::string_view text);
/// The canonical form the kernel prints ("le:s16/16>>0", with "X<repeat>" when repeat > 1).
std::string format_scan_type(const ScanType& type);

/// `text` without trailing '\n', '\0', '\r', blanks and without leading blanks.
std::string_view trim_sysfs(std::string_view text) noexcept;

/// Strict numbers of a sysfs value (after trim_sysfs). `what` names the source in the error
/// ("<path>"). Throws IioError on empty text, garbage, trailing characters, out of range, inf/nan.
double parse_sysfs_double(std::string_view text, std::string_view what);
std::int64_t parse_sysfs_int(std::string_view text, std::string_view what);

/// A row-major 3x3 matrix; applied as out = M * in.
using Matrix3 = std::array<std::array<double, 3>, 3>;
constexpr Matrix3 kIdentity3{{{1.0, 0.0, 0.0}, {0.0, 1.0, 0.0}, {0.0, 0.0, 1.0}}};
/// Parses a mount matrix file ("x1, y1, z1; x2, y2, z2; x3, y3, z3": rows separated by ';', values by
/// ','). Throws IioError naming `what`.
Matrix3 parse_mount_matrix(std::string_view text, std::string_view what);

// ------------------------------------------------------------------ files

/// Whole content of a sysfs file, trimmed. Throws IioError("cannot read <path>: <strerror>").
std::string read_sysfs(const std::string& path);
/// Like read_sysfs but false (out untouched) when the file does not exist; other errors throw.
bool read_sysfs_optional(const std::string& path, std::string& out);
/// Writes `value` to a sysfs file (O_WRONLY|O_TRUNC, the way `echo v > file` does). Throws IioError
/// naming the path and the value on failure.
void write_sysfs(const std::string& path, std::string_view value);
/// read_sysfs + parse_sysfs_double / parse_sysfs_int (errors name the path).
double read_sysfs_double(const std::string& path);
std::int64_t read_sysfs_int(const std::string& path);

// ------------------------------------------------------------------ channels and layout

/// One channel of scan_elements/: in_<name>_en, in_<name>_index, in_<name>_type.
struct ScanChannel {
  std::string name;  ///< e.g. "in_accel_x", "in_timestamp"
  bool enabled = false;
  std::int64_t index = 0;
  ScanType type;
};

/// Every channel of a scan_elements directory, sorted by index. Throws IioError naming the file when
/// one of a channel's three files is missing or malformed, or two channels share an index. An absent
/// directory yields an empty list (the device has no buffer).
std::vector<ScanChannel> discover_scan_elements(const std::string& scan_elements_dir);

/// Where each enabled channel sits in one scan.
struct ScanSlot {
  std::string name;
  std::int64_t index = 0;
  ScanType type;
  std::size_t offset = 0;  ///< byte offset in the scan
};
struct ScanLayout {
  std::vector<ScanSlot> slots;  ///< enabled channels in index order
  std::size_t scan_bytes = 0;   ///< size of one scan, padding included
  /// Slot of `name`, nullptr when absent (or not enabled).
  const ScanSlot* find(std::string_view name) const noexcept;
};
/// The layout of a scan with the enabled ones of `channels` (kernel rules, see the top of this file).
/// Throws IioError when no channel is enabled or two enabled channels share an index.
ScanLayout compute_layout(const std::vector<ScanChannel>& channels);

/// [RT] Element `element` (0..repeat-1) of the channel at `offset` of `scan`: the raw storage word
/// in the channel's byte order, shifted, masked to `bits` and sign-extended when signed.
std::int64_t unpack_value(const std::uint8_t* scan, std::size_t offset, const ScanType& type,
                          unsigned element = 0) noexcept;
/// [RT] Stores `value` in the channel's format (inverse of unpack_value: the value is shifted left by
/// `shift` and masked); for tests and fake devices.
void pack_value(std::uint8_t* scan, std::size_t offset, const ScanType& type, std::int64_t value,
                unsigned element = 0) noexcept;

}  // namespace locus::hal::iio
