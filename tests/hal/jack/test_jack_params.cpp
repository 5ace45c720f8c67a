// The `jack` source/sink parameters and the errors a user sees without a running server: schema
// defaults, every validation message naming its key, "no JACK server" at open(), the registry
// entries, and `locus devices` reporting JACK as unavailable instead of failing.
#include <gtest/gtest.h>
#include <unistd.h>

#include <string>

#include "jack/jack_backend.hpp"
#include "jack/jack_devices.hpp"
#include "locus/registry.hpp"
#include "support/test_host.hpp"

namespace locus::hal::jack {
namespace {

Params source_params() { return Params::defaults(jack_source_schema()); }

std::string error_of(const Params& p) {
  try {
    JackParams::from_params(p);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

std::string missing_server() { return "locus_jack_none_" + std::to_string(::getpid()); }

TEST(JackParams, DefaultsAreValid) {
  const JackParams j = JackParams::from_params(source_params());
  EXPECT_EQ(j.server, "");
  EXPECT_EQ(j.client_name, "locus");
  EXPECT_EQ(j.channels, 1u);
  EXPECT_EQ(j.connect, "");
  EXPECT_DOUBLE_EQ(j.reconnect.backoff_s, 0.5);
  EXPECT_EQ(j.reconnect.max_attempts, 0);
  const JackParams s = JackParams::from_params(Params::defaults(jack_sink_schema()));
  EXPECT_EQ(s.client_name, "locus");
}

TEST(JackParams, BadValuesAreRefusedNamingTheKey) {
  Params p = source_params();
  p.set("connect", std::string("system:capture_(["));
  EXPECT_NE(error_of(p).find("connect 'system:capture_(['"), std::string::npos) << error_of(p);
  p = source_params();
  p.set("client_name", std::string("a:b"));
  EXPECT_NE(error_of(p).find("client_name 'a:b' must not contain ':'"), std::string::npos) << error_of(p);
  p = source_params();
  p.set("client_name", std::string(""));
  EXPECT_NE(error_of(p).find("client_name must not be empty"), std::string::npos);
  p = source_params();
  p.set("client_name", std::string(200, 'x'));
  EXPECT_NE(error_of(p).find("is longer than JACK's"), std::string::npos);
  p = source_params();
  p.set("channels", std::int64_t{0});
  EXPECT_NE(error_of(p).find("channels must be 1..64"), std::string::npos);
  p = source_params();
  p.set("reconnect_max", std::int64_t{-1});
  EXPECT_NE(error_of(p).find("reconnect_max"), std::string::npos);
  p = source_params();
  p.set("reconnect_backoff_s", 0.0);
  EXPECT_NE(error_of(p).find("reconnect_backoff_s"), std::string::npos);
}

TEST(JackSource, OpenWithoutAServerFailsClearlyAndQuickly) {
  test::RecordingLogger log;
  JackParams j;
  j.server = missing_server();
  JackSource src;
  try {
    src.open(j, log);
    FAIL() << "open succeeded without a server";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("no JACK server '" + j.server + "' is running"), std::string::npos) << e.what();
  }
  JackSink sink;
  EXPECT_THROW(sink.open(j, log), std::runtime_error);
  EXPECT_FALSE(src.finished());
  EXPECT_EQ(src.error(), "");
  src.stop();  // harmless before a successful open
}

TEST(JackDevices, NoServerGivesOneUnavailableEntry) {
  const auto list = hal::list_jack_ports(missing_server());
  ASSERT_EQ(list.size(), 1u);
  EXPECT_EQ(list[0].backend, "jack");
  EXPECT_EQ(list[0].kind, "unavailable");
  EXPECT_EQ(list[0].id, missing_server());
  EXPECT_NE(list[0].description.find("no JACK server"), std::string::npos) << list[0].description;
}

TEST(JackRegistry, SourceAndSinkAreBuiltIn) {
  Registry r;
  register_builtins(r);
  const SourceDescriptor* s = r.find_source("jack");
  ASSERT_NE(s, nullptr);
  EXPECT_NE(r.find_sink("jack"), nullptr);
  bool has_connect = false;
  for (const ParamSpec& spec : s->schema) has_connect |= spec.key == "connect";
  EXPECT_TRUE(has_connect);
  EXPECT_TRUE(s->create() != nullptr);
}

}  // namespace
}  // namespace locus::hal::jack
