// Params getters, Params::defaults and param_type_name.
#include <gtest/gtest.h>

#include <functional>
#include <stdexcept>
#include <string>

#include "locus/params.hpp"

namespace locus {
namespace {

std::string out_of_range_message(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::out_of_range& e) {
    return e.what();
  }
  return "(no exception)";
}

TEST(Params, TypedGettersReturnStoredValues) {
  Params p;
  p.set("on", true);
  p.set("n", std::int64_t{7});
  p.set("x", 0.25);
  p.set("s", std::string("hello"));
  p.set("l", std::vector<double>{1.0, 2.5});
  EXPECT_TRUE(p.get_bool("on"));
  EXPECT_EQ(p.get_int("n"), 7);
  EXPECT_DOUBLE_EQ(p.get_float("x"), 0.25);
  EXPECT_EQ(p.get_string("s"), "hello");
  EXPECT_EQ(p.get_floats("l"), (std::vector<double>{1.0, 2.5}));
  EXPECT_TRUE(p.has("x"));
  EXPECT_FALSE(p.has("y"));
}

TEST(Params, GetFloatAcceptsAnInteger) {
  Params p;
  p.set("n", std::int64_t{3});
  EXPECT_DOUBLE_EQ(p.get_float("n"), 3.0);
}

TEST(Params, AbsentKeyIsNamed) {
  Params p;
  EXPECT_EQ(out_of_range_message([&] { p.get_float("threshold_db"); }), "parameter 'threshold_db' is not set");
  p.set("req", std::monostate{});
  EXPECT_EQ(out_of_range_message([&] { p.get_int("req"); }), "parameter 'req' is not set");
}

TEST(Params, WrongTypeIsNamed) {
  Params p;
  p.set("x", 0.5);
  p.set("n", std::int64_t{1});
  p.set("s", std::string("a"));
  EXPECT_EQ(out_of_range_message([&] { p.get_bool("x"); }), "parameter 'x' is a float, not a bool");
  EXPECT_EQ(out_of_range_message([&] { p.get_int("x"); }), "parameter 'x' is a float, not an integer");
  EXPECT_EQ(out_of_range_message([&] { p.get_string("n"); }), "parameter 'n' is an integer, not a string");
  EXPECT_EQ(out_of_range_message([&] { p.get_floats("s"); }), "parameter 's' is a string, not a list of floats");
  EXPECT_EQ(out_of_range_message([&] { p.get_float("s"); }), "parameter 's' is a string, not a float");
}

TEST(Params, DefaultsHoldEveryOptionalKey) {
  const auto spec = [](std::string key, ParamType type, ParamValue def) {
    ParamSpec s;
    s.key = std::move(key);
    s.type = type;
    s.default_value = std::move(def);
    return s;
  };
  ParamSchema schema;
  schema.push_back(spec("gain_db", ParamType::Float, -6.0));
  schema.push_back(spec("order", ParamType::Int, std::int64_t{4}));
  schema.push_back(spec("as_int", ParamType::Float, std::int64_t{2}));
  schema.push_back(spec("mode", ParamType::Enum, std::string("fast")));
  schema.back().choices = {"fast", "slow"};
  schema.push_back(spec("needed", ParamType::Float, {}));  // required
  const Params p = Params::defaults(schema);
  EXPECT_DOUBLE_EQ(p.get_float("gain_db"), -6.0);
  EXPECT_EQ(p.get_int("order"), 4);
  // An integer default of a Float parameter is stored as a float.
  EXPECT_TRUE(std::holds_alternative<double>(p.values().at("as_int")));
  EXPECT_EQ(p.get_string("mode"), "fast");
  EXPECT_FALSE(p.has("needed"));
  EXPECT_EQ(p.values().size(), 4u);
}

TEST(Params, TypeNames) {
  EXPECT_EQ(param_type_name(ParamType::Bool), "bool");
  EXPECT_EQ(param_type_name(ParamType::Int), "integer");
  EXPECT_EQ(param_type_name(ParamType::Float), "float");
  EXPECT_EQ(param_type_name(ParamType::String), "string");
  EXPECT_EQ(param_type_name(ParamType::Enum), "enum");
  EXPECT_EQ(param_type_name(ParamType::FloatList), "list of floats");
}

}  // namespace
}  // namespace locus
