// `locus devices`: list_all_devices asks every backend and never fails (a backend that cannot look
// gives one "unavailable" entry); a fake IIO tree under --iio-root is listed; a JACK server that does
// not run is reported, not thrown; the table is aligned and one line per entry; the JSON is an array
// of {backend, kind, id, description}. An optional backend this build lacks (LOCUS_WITH_<X>) is one
// "not-built-in" entry saying why; the checks follow the build's own table (locus/build_options.hpp),
// so they hold in the full build and in the minimal one.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "devices/device_list.hpp"
#include "locus/build_options.hpp"

namespace fs = std::filesystem;
using locus::app::DevicesOptions;
using locus::hal::DeviceInfo;

namespace {

struct FakeIioTree {
  fs::path root;
  FakeIioTree() {
    root = fs::temp_directory_path() / ("locus_devices_test_" + std::to_string(::getpid()));
    fs::remove_all(root);
    const fs::path dev = root / "sys/bus/iio/devices/iio:device0";
    fs::create_directories(dev / "scan_elements");
    fs::create_directories(dev / "buffer");
    fs::create_directories(root / "dev");
    const auto put = [&](const fs::path& p, const std::string& v) { std::ofstream(p) << v << "\n"; };
    put(dev / "name", "lsm6dsl");
    put(dev / "sampling_frequency", "104");
    for (const char* ax : {"x", "y", "z"}) {
      put(dev / (std::string("in_accel_") + ax + "_raw"), "100");
      put(dev / (std::string("in_anglvel_") + ax + "_raw"), "-3");
    }
    put(dev / "in_accel_scale", "0.000598");
    put(dev / "in_anglvel_scale", "0.000153");
  }
  ~FakeIioTree() {
    std::error_code ec;
    fs::remove_all(root, ec);
  }
};

}  // namespace

TEST(Devices, EveryBackendAnswersAndTheFakeIioDeviceIsListed) {
  FakeIioTree tree;
  DevicesOptions o;
  o.iio_root = tree.root.string();
  o.jack_server = "locus_no_such_server_" + std::to_string(::getpid());
  const std::vector<DeviceInfo> all = locus::app::list_all_devices(o);
  std::set<std::string> backends;
  for (const auto& d : all) backends.insert(d.backend);
  EXPECT_EQ(backends, (std::set<std::string>{"alsa", "jack", "iio", "bluez"}));

  bool iio = false;
  for (const auto& d : all) {
    if (d.backend == "iio" && d.id == "iio:device0") {
      iio = true;
      EXPECT_EQ(d.kind, "imu") << d.description;
      EXPECT_NE(d.description.find("lsm6dsl"), std::string::npos) << d.description;
    }
  }
  EXPECT_TRUE(iio);
  // No such JACK server: one entry saying so, with a reason (or, without JACK support, that it was not
  // built in).
  const bool jack_built = locus::build::find_optional_backend("jack")->built;
  std::size_t jack = 0;
  for (const auto& d : all) {
    if (d.backend != "jack") continue;
    ++jack;
    EXPECT_EQ(d.kind, jack_built ? "unavailable" : locus::app::kNotBuiltKind) << d.kind;
    EXPECT_FALSE(d.description.empty());
  }
  EXPECT_EQ(jack, 1u);
}

TEST(Devices, ABackendNotBuiltInIsOneEntrySayingWhy) {
  FakeIioTree tree;
  DevicesOptions o;
  o.iio_root = tree.root.string();
  o.jack_server = "locus_no_such_server_" + std::to_string(::getpid());
  const std::vector<DeviceInfo> all = locus::app::list_all_devices(o);
  for (const char* name : {"alsa", "jack", "bluez"}) {
    const locus::build::OptionalBackend* b = locus::build::find_optional_backend(name);
    ASSERT_NE(b, nullptr) << name;
    std::size_t entries = 0;
    std::size_t not_built = 0;
    for (const auto& d : all) {
      if (d.backend != name) continue;
      ++entries;
      if (d.kind != locus::app::kNotBuiltKind) continue;
      ++not_built;
      EXPECT_EQ(d.id, "");
      EXPECT_EQ(d.description, locus::build::not_built_reason(*b));
    }
    if (b->built) {
      EXPECT_EQ(not_built, 0u) << name << " is built in";
    } else {
      EXPECT_EQ(entries, 1u) << name;
      EXPECT_EQ(not_built, 1u) << name << " is not built in";
    }
  }
}

TEST(Devices, NotBuiltEntryNamesTheOptionAndTheLibrary) {
  // The sentence itself, for a backend switched off and one whose library was not found.
  const locus::build::OptionalBackend off{"jack", "JACK", "LOCUS_WITH_JACK", "libjack", false, "LOCUS_WITH_JACK=OFF"};
  EXPECT_EQ(locus::build::not_built_reason(off), "JACK support was not built in (LOCUS_WITH_JACK=OFF)");
  const locus::build::OptionalBackend built{"jack", "JACK", "LOCUS_WITH_JACK", "libjack", true, ""};
  EXPECT_EQ(locus::build::not_built_reason(built), "");
  // Every optional backend of this build: a reason naming its option exactly when it is not built.
  for (const locus::build::OptionalBackend& b : locus::build::kOptionalBackends) {
    const std::string why = locus::build::not_built_reason(b);
    if (b.built) {
      EXPECT_EQ(why, "") << b.name;
    } else {
      EXPECT_EQ(why.rfind(std::string(b.title) + " support was not built in (" + std::string(b.option) + "=", 0), 0u)
          << why;
    }
  }
  // The entry's shape and how the table prints it.
  const DeviceInfo e = locus::app::not_built_entry("bluez");
  EXPECT_EQ(e.backend, "bluez");
  EXPECT_EQ(e.kind, "not-built-in");
  EXPECT_EQ(e.id, "");
  EXPECT_THROW(locus::app::not_built_entry("iio"), std::invalid_argument);  // iio is always built
  const std::string t = locus::app::format_devices_table(
      {{"jack", "not-built-in", "", "JACK support was not built in (LOCUS_WITH_JACK=OFF)"}});
  EXPECT_NE(t.find("jack     not-built-in  -   JACK support was not built in (LOCUS_WITH_JACK=OFF)\n"),
            std::string::npos)
      << t;
}

TEST(Devices, TableIsAlignedOneLinePerEntry) {
  const std::vector<DeviceInfo> list{{"alsa", "pcm", "hw:1,0", "USB Audio: capture 2 ch"},
                                     {"jack", "unavailable", "", "no server 'x'\n(retry later)"},
                                     {"iio", "imu", "iio:device0", "lsm6dsl"}};
  const std::string t = locus::app::format_devices_table(list);
  std::istringstream is(t);
  std::vector<std::string> lines;
  for (std::string l; std::getline(is, l);) lines.push_back(l);
  ASSERT_EQ(lines.size(), 4u);
  EXPECT_EQ(lines[0].rfind("BACKEND", 0), 0u);
  const std::size_t desc = lines[0].find("DESCRIPTION");
  const std::size_t id = lines[0].find("ID");
  EXPECT_EQ(lines[1].find("USB Audio"), desc);
  EXPECT_EQ(lines[1].find("hw:1,0"), id);
  EXPECT_EQ(lines[3].find("iio:device0"), id);
  EXPECT_EQ(lines[2].find("no server 'x' (retry later)"), desc);  // line break flattened
  EXPECT_EQ(lines[2].find('-', id), id);                           // empty id shown as '-'
}

TEST(Devices, JsonIsAnArrayOfObjects) {
  const std::vector<DeviceInfo> list{{"bluez", "adapter", "hci0", "AA:BB:CC:DD:EE:FF \"lab\""},
                                     {"alsa", "card", "hw:0", std::string("bad \xff utf8")}};
  const auto j = nlohmann::json::parse(locus::app::format_devices_json(list));
  ASSERT_TRUE(j.is_array());
  ASSERT_EQ(j.size(), 2u);
  EXPECT_EQ(j[0]["backend"], "bluez");
  EXPECT_EQ(j[0]["kind"], "adapter");
  EXPECT_EQ(j[0]["id"], "hci0");
  EXPECT_EQ(j[0]["description"], "AA:BB:CC:DD:EE:FF \"lab\"");
  EXPECT_EQ(j[1]["id"], "hw:0");
  EXPECT_EQ(locus::app::format_devices_json({}), "[]");
}
