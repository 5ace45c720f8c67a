// Parsing helpers of the BlueZ backend: Bluetooth addresses (text <-> bytes, the object paths BlueZ
// gives devices) and the typed values BlueZ puts in D-Bus property dictionaries (RSSI, TxPower).
//
// Why separate from the scanner: everything that reads what another process sent us lives here, as
// pure functions that unit tests can feed with malformed input (a wrong variant type, a mangled
// address, an out-of-range RSSI) without a bus. The scanner never trusts a D-Bus value without going
// through these. [main] (plain functions; they allocate).
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <sdbus-c++/Types.h>

namespace locus::hal::bluez {

/// A Bluetooth device address, most significant byte first (as written "AA:BB:CC:DD:EE:FF").
using MacAddress = std::array<std::uint8_t, 6>;

/// "AA:BB:CC:DD:EE:FF" (hex digits in either case, ':' separators, exactly 17 characters) -> bytes;
/// nullopt for anything else ("AA-BB-...", "AABBCCDDEEFF", a missing or extra octet, non-hex digits).
std::optional<MacAddress> parse_mac(std::string_view text) noexcept;

/// Bytes -> "AA:BB:CC:DD:EE:FF" (upper case, the form BlueZ uses).
std::string format_mac(const MacAddress& address);

/// The object path BlueZ gives an adapter: "/org/bluez/<adapter>" (e.g. "/org/bluez/hci0").
std::string adapter_object_path(std::string_view adapter);

/// True for an adapter name that can be part of an object path ("hci0": [A-Za-z0-9_]+).
bool valid_adapter_name(std::string_view adapter) noexcept;

/// The address encoded in a device object path "<adapter path>/dev_AA_BB_CC_DD_EE_FF"; nullopt when
/// the path is not a device directly under `adapter_path` or the encoded address is malformed.
/// An empty `adapter_path` accepts a device under any adapter ("/org/bluez/<any>/dev_...").
std::optional<MacAddress> address_from_device_path(std::string_view path, std::string_view adapter_path = {});

/// A comma-separated allow list ("AA:BB:CC:DD:EE:01, aa:bb:cc:dd:ee:02"; spaces around entries are
/// ignored; "" = empty list). Throws std::invalid_argument naming the bad entry and its position.
std::vector<MacAddress> parse_address_list(std::string_view text);

/// An integer property read from a D-Bus property dictionary.
struct IntProperty {
  enum class Status : std::uint8_t {
    Absent,      ///< the key is not in the dictionary
    Ok,          ///< `value` holds it
    WrongType,   ///< not an integer (or an empty variant); `type` holds the D-Bus signature found
    OutOfRange,  ///< an integer outside [min, max]; `value` holds it (clamped to int64)
  };
  Status status = Status::Absent;
  std::int64_t value = 0;
  std::string type;  ///< D-Bus signature of the value found ("n" for BlueZ's int16)

  bool ok() const noexcept { return status == Status::Ok; }
  /// "" when Absent/Ok, else e.g. "RSSI has D-Bus type 's' (expected an integer, BlueZ sends int16 'n')".
  std::string problem(std::string_view key) const;
};

using PropertyMap = std::map<std::string, sdbus::Variant>;

/// Reads `key` as an integer within [min, max]. BlueZ sends RSSI and TxPower as int16 ('n'); any other
/// D-Bus integer type ('y', 'q', 'i', 'u', 'x', 't') is accepted when its value is in range (a
/// tolerant reading of a misbehaving peer), anything else is WrongType. Throws only std::bad_alloc.
IntProperty read_int_property(const PropertyMap& props, const std::string& key, std::int64_t min,
                              std::int64_t max);

/// Plausible ranges (dBm) for what BlueZ reports: RSSI is -127..+20, TxPower -127..+20.
inline constexpr std::int64_t kMinDbm = -127;
inline constexpr std::int64_t kMaxDbm = 20;

/// What one org.bluez.Device1 property dictionary (InterfacesAdded, PropertiesChanged,
/// GetManagedObjects) says about an advertisement.
struct DeviceProperties {
  std::optional<MacAddress> address;  ///< from the "Address" string property (nullopt: absent/malformed)
  bool address_malformed = false;     ///< "Address" present but not a string "AA:BB:CC:DD:EE:FF"
  IntProperty rssi;                   ///< "RSSI"
  IntProperty tx_power;               ///< "TxPower"
};
DeviceProperties parse_device_properties(const PropertyMap& props);

}  // namespace locus::hal::bluez
