// Unit tests of the BlueZ backend without bluetoothd: address parsing both ways, object paths,
// the allow list, reading RSSI/TxPower out of D-Bus variant dictionaries (right and wrong types),
// params -> config validation, the registration, and the clear errors when there is no system bus.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>

#include "bluez/bluez_devices.hpp"
#include "bluez/bluez_parse.hpp"
#include "bluez/bluez_scanner.hpp"
#include "locus/registry.hpp"
#include "support/test_host.hpp"

namespace locus::hal::bluez {
namespace {

TEST(BluezMac, ParsesBothCasesMsbFirst) {
  const auto a = parse_mac("AA:bb:0C:d1:E2:f3");
  ASSERT_TRUE(a.has_value());
  const MacAddress expect{0xAA, 0xBB, 0x0C, 0xD1, 0xE2, 0xF3};
  EXPECT_EQ(*a, expect);
  EXPECT_EQ(format_mac(*a), "AA:BB:0C:D1:E2:F3");
  const auto z = parse_mac("00:00:00:00:00:00");
  ASSERT_TRUE(z.has_value());
  EXPECT_EQ(format_mac(*z), "00:00:00:00:00:00");
}

TEST(BluezMac, RoundTripsEveryByteValue) {
  for (int v = 0; v < 256; ++v) {
    MacAddress m{};
    for (std::size_t i = 0; i < 6; ++i) m[i] = static_cast<std::uint8_t>((v + 37 * static_cast<int>(i)) & 0xff);
    const auto back = parse_mac(format_mac(m));
    ASSERT_TRUE(back.has_value()) << format_mac(m);
    EXPECT_EQ(*back, m);
  }
}

TEST(BluezMac, RejectsMalformed) {
  for (const char* bad : {"", "AA:BB:CC:DD:EE", "AA:BB:CC:DD:EE:FF:00", "AA-BB-CC-DD-EE-FF", "AABBCCDDEEFF",
                          "AA:BB:CC:DD:EE:FG", "AA:BB:CC:DD:EE:F", " AA:BB:CC:DD:EE:FF", "AA:BB:CC:DD:EE:FF ",
                          "AA:BB:CC:DD:EEE:F", "AA_BB_CC_DD_EE_FF", "+A:BB:CC:DD:EE:FF"}) {
    EXPECT_FALSE(parse_mac(bad).has_value()) << "'" << bad << "'";
  }
}

TEST(BluezPath, DeviceAddressFromObjectPath) {
  const MacAddress expect{0xAA, 0xBB, 0xCC, 0xDD, 0xEE, 0x01};
  EXPECT_EQ(adapter_object_path("hci0"), "/org/bluez/hci0");
  auto a = address_from_device_path("/org/bluez/hci0/dev_AA_BB_CC_DD_EE_01", "/org/bluez/hci0");
  ASSERT_TRUE(a.has_value());
  EXPECT_EQ(*a, expect);
  a = address_from_device_path("/org/bluez/hci1/dev_aa_bb_cc_dd_ee_01");  // any adapter
  ASSERT_TRUE(a.has_value());
  EXPECT_EQ(*a, expect);
  // Another adapter, a GATT object below a device, the adapter itself, garbage.
  EXPECT_FALSE(address_from_device_path("/org/bluez/hci1/dev_AA_BB_CC_DD_EE_01", "/org/bluez/hci0"));
  EXPECT_FALSE(address_from_device_path("/org/bluez/hci10/dev_AA_BB_CC_DD_EE_01", "/org/bluez/hci1"));
  EXPECT_FALSE(address_from_device_path("/org/bluez/hci0/dev_AA_BB_CC_DD_EE_01/service0001", "/org/bluez/hci0"));
  EXPECT_FALSE(address_from_device_path("/org/bluez/hci0/dev_AA_BB_CC_DD_EE_01/service0001"));
  EXPECT_FALSE(address_from_device_path("/org/bluez/hci0", "/org/bluez/hci0"));
  EXPECT_FALSE(address_from_device_path("/org/bluez/hci0/", "/org/bluez/hci0"));
  EXPECT_FALSE(address_from_device_path("/org/bluez/hci0/dev_AA:BB:CC:DD:EE:01", "/org/bluez/hci0"));
  EXPECT_FALSE(address_from_device_path("/org/bluez/hci0/dev_AA_BB_CC_DD_EE", "/org/bluez/hci0"));
  EXPECT_FALSE(address_from_device_path("/org/bluez/hci0/xdev_AA_BB_CC_DD_EE_01", "/org/bluez/hci0"));
  EXPECT_FALSE(address_from_device_path("/org/bluez//dev_AA_BB_CC_DD_EE_01"));
  EXPECT_FALSE(address_from_device_path("/com/example/hci0/dev_AA_BB_CC_DD_EE_01"));
}

TEST(BluezPath, AdapterNames) {
  EXPECT_TRUE(valid_adapter_name("hci0"));
  EXPECT_TRUE(valid_adapter_name("hci_12"));
  EXPECT_FALSE(valid_adapter_name(""));
  EXPECT_FALSE(valid_adapter_name("hci0/dev"));
  EXPECT_FALSE(valid_adapter_name("hci-0"));
  EXPECT_FALSE(valid_adapter_name("hci 0"));
}

TEST(BluezAllowList, ParsesAndNamesTheBadEntry) {
  EXPECT_TRUE(parse_address_list("").empty());
  EXPECT_TRUE(parse_address_list("   ").empty());
  const auto l = parse_address_list(" AA:BB:CC:DD:EE:01,aa:bb:cc:dd:ee:02 ");
  ASSERT_EQ(l.size(), 2u);
  EXPECT_EQ(format_mac(l[0]), "AA:BB:CC:DD:EE:01");
  EXPECT_EQ(format_mac(l[1]), "AA:BB:CC:DD:EE:02");
  try {
    parse_address_list("AA:BB:CC:DD:EE:01, nonsense");
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("entry 2 'nonsense'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("AA:BB:CC:DD:EE:FF"), std::string::npos) << e.what();
  }
  EXPECT_THROW(parse_address_list("AA:BB:CC:DD:EE:01,"), std::invalid_argument);  // empty trailing entry
  EXPECT_THROW(parse_address_list(",AA:BB:CC:DD:EE:01"), std::invalid_argument);
}

TEST(BluezProperties, ReadsInt16AndToleratesOtherIntegers) {
  PropertyMap props;
  props["RSSI"] = sdbus::Variant(static_cast<std::int16_t>(-63));
  props["TxPower"] = sdbus::Variant(static_cast<std::int32_t>(4));  // wrong width, plausible value
  auto r = read_int_property(props, "RSSI", kMinDbm, kMaxDbm);
  EXPECT_EQ(r.status, IntProperty::Status::Ok);
  EXPECT_EQ(r.value, -63);
  EXPECT_EQ(r.type, "n");
  auto t = read_int_property(props, "TxPower", kMinDbm, kMaxDbm);
  EXPECT_EQ(t.status, IntProperty::Status::Ok);
  EXPECT_EQ(t.value, 4);
  EXPECT_EQ(t.type, "i");
  EXPECT_EQ(read_int_property(props, "Missing", kMinDbm, kMaxDbm).status, IntProperty::Status::Absent);
  props["U8"] = sdbus::Variant(static_cast<std::uint8_t>(7));
  props["U64"] = sdbus::Variant(static_cast<std::uint64_t>(~0ull));
  EXPECT_EQ(read_int_property(props, "U8", kMinDbm, kMaxDbm).value, 7);
  EXPECT_EQ(read_int_property(props, "U64", kMinDbm, kMaxDbm).status, IntProperty::Status::OutOfRange);
}

TEST(BluezProperties, WrongTypesAndRangesAreReportedNotThrown) {
  PropertyMap props;
  props["RSSI"] = sdbus::Variant(std::string("-60"));
  props["TxPower"] = sdbus::Variant(3.5);
  props["Big"] = sdbus::Variant(static_cast<std::int16_t>(127));  // HCI "RSSI not available"
  props["Empty"] = sdbus::Variant();
  props["Bool"] = sdbus::Variant(true);
  auto r = read_int_property(props, "RSSI", kMinDbm, kMaxDbm);
  EXPECT_EQ(r.status, IntProperty::Status::WrongType);
  EXPECT_EQ(r.type, "s");
  EXPECT_NE(r.problem("RSSI").find("RSSI has D-Bus type 's'"), std::string::npos) << r.problem("RSSI");
  EXPECT_EQ(read_int_property(props, "TxPower", kMinDbm, kMaxDbm).status, IntProperty::Status::WrongType);
  EXPECT_EQ(read_int_property(props, "Bool", kMinDbm, kMaxDbm).status, IntProperty::Status::WrongType);
  EXPECT_EQ(read_int_property(props, "Empty", kMinDbm, kMaxDbm).status, IntProperty::Status::WrongType);
  auto big = read_int_property(props, "Big", kMinDbm, kMaxDbm);
  EXPECT_EQ(big.status, IntProperty::Status::OutOfRange);
  EXPECT_EQ(big.value, 127);
  EXPECT_NE(big.problem("RSSI").find("127"), std::string::npos);
}

TEST(BluezProperties, DeviceDictionary) {
  PropertyMap props;
  props["Address"] = sdbus::Variant(std::string("aa:bb:cc:dd:ee:0f"));
  props["RSSI"] = sdbus::Variant(static_cast<std::int16_t>(-71));
  props["TxPower"] = sdbus::Variant(static_cast<std::int16_t>(-8));
  props["Name"] = sdbus::Variant(std::string("tag"));
  auto p = parse_device_properties(props);
  ASSERT_TRUE(p.address.has_value());
  EXPECT_EQ(format_mac(*p.address), "AA:BB:CC:DD:EE:0F");
  EXPECT_FALSE(p.address_malformed);
  EXPECT_TRUE(p.rssi.ok());
  EXPECT_EQ(p.rssi.value, -71);
  EXPECT_TRUE(p.tx_power.ok());
  EXPECT_EQ(p.tx_power.value, -8);

  PropertyMap bad;
  bad["Address"] = sdbus::Variant(static_cast<std::uint32_t>(5));
  bad["RSSI"] = sdbus::Variant(std::vector<std::uint8_t>{1, 2});
  auto q = parse_device_properties(bad);
  EXPECT_FALSE(q.address.has_value());
  EXPECT_TRUE(q.address_malformed);
  EXPECT_EQ(q.rssi.status, IntProperty::Status::WrongType);
  EXPECT_EQ(q.rssi.type, "ay");
  EXPECT_EQ(q.tx_power.status, IntProperty::Status::Absent);

  PropertyMap garbled;
  garbled["Address"] = sdbus::Variant(std::string("AA:BB:CC:DD:EE"));
  EXPECT_TRUE(parse_device_properties(garbled).address_malformed);
}

// ------------------------------------------------------------------ config and registration

Params params_with(std::initializer_list<std::pair<std::string, ParamValue>> kv) {
  Params p = Params::defaults(bluez_schema());
  for (const auto& [k, v] : kv) p.set(k, v);
  return p;
}

TEST(BluezConfig, DefaultsAndValidation) {
  const BluezConfig c = bluez_config_from_params(params_with({}));
  EXPECT_EQ(c.adapter, "hci0");
  EXPECT_TRUE(c.duplicate_data);
  EXPECT_EQ(c.rssi_threshold_dbm, BluezConfig::kNoRssiThreshold);
  EXPECT_TRUE(c.addresses.empty());
  EXPECT_GT(c.restart_backoff_s, 0.0);

  const BluezConfig d = bluez_config_from_params(params_with(
      {{"adapter", std::string("hci1")}, {"addresses", std::string("AA:BB:CC:DD:EE:01")},
       {"rssi_threshold_dbm", std::int64_t{-90}}, {"duplicate_data", false}}));
  EXPECT_EQ(d.adapter, "hci1");
  EXPECT_EQ(d.addresses.size(), 1u);
  EXPECT_EQ(d.rssi_threshold_dbm, -90);
  EXPECT_FALSE(d.duplicate_data);

  try {
    bluez_config_from_params(params_with({{"adapter", std::string("hci0/x")}}));
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("adapter 'hci0/x'"), std::string::npos) << e.what();
  }
  try {
    bluez_config_from_params(params_with({{"addresses", std::string("AA:BB:CC:DD:EE:01;AA:BB:CC:DD:EE:02")}}));
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("addresses: entry 1"), std::string::npos) << e.what();
  }
}

TEST(BluezRegistry, RegisteredAsBleSensorSource) {
  Registry r;
  register_builtins(r);
  const SensorSourceDescriptor* d = r.find_sensor_source("bluez");
  ASSERT_NE(d, nullptr);
  EXPECT_EQ(d->kind, SensorKind::Ble);
  auto src = r.create_sensor_source("bluez");
  ASSERT_NE(src, nullptr);
  EXPECT_EQ(src->kind(), SensorKind::Ble);
  EXPECT_TRUE(src->live());
  EXPECT_FALSE(src->finished());
}

// ------------------------------------------------------------------ no bus

class BluezNoBus : public ::testing::Test {
 protected:
  void SetUp() override {
    const char* old = std::getenv("DBUS_SYSTEM_BUS_ADDRESS");
    had_ = old != nullptr;
    if (had_) old_ = old;
    missing_ = (std::filesystem::temp_directory_path() / ("locus-bluez-no-bus-" + std::to_string(::getpid()))).string();
    setenv("DBUS_SYSTEM_BUS_ADDRESS", ("unix:path=" + missing_).c_str(), 1);
  }
  void TearDown() override {
    if (had_) setenv("DBUS_SYSTEM_BUS_ADDRESS", old_.c_str(), 1);
    else unsetenv("DBUS_SYSTEM_BUS_ADDRESS");
  }
  bool had_ = false;
  std::string old_, missing_;
};

TEST_F(BluezNoBus, OpenThrowsNamingTheBus) {
  test::TestHost host;
  HostContext ctx = host.context("ble", "A");
  BluezScanner s;
  try {
    s.open(Params::defaults(bluez_schema()), ctx);
    FAIL() << "open() succeeded without a bus";
  } catch (const std::runtime_error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("system bus"), std::string::npos) << msg;
    EXPECT_NE(msg.find(missing_), std::string::npos) << msg;
  }
  SensorQueue q(16);
  EXPECT_THROW(s.start(q), std::runtime_error);  // start() before a successful open()
}

TEST_F(BluezNoBus, DeviceListSaysUnavailable) {
  const auto list = list_bluez_adapters(0.5);
  ASSERT_EQ(list.size(), 1u);
  EXPECT_EQ(list[0].backend, "bluez");
  EXPECT_EQ(list[0].kind, "unavailable");
  EXPECT_NE(list[0].description.find(missing_), std::string::npos) << list[0].description;
}

}  // namespace
}  // namespace locus::hal::bluez
