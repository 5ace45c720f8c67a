// The estimates reader: what it accepts, and one test per kind of malformed line, each checking the
// file:line:column and what was expected.
#include <gtest/gtest.h>

#include <cmath>

#include "eval_test_support.hpp"
#include "locus/eval/error.hpp"

namespace locus::eval {
namespace {

/// The messages of the InputError thrown for `lines`.
std::vector<std::string> errors_for(const std::vector<std::string>& lines) {
  try {
    test::parse_lines(lines, "run.jsonl");
  } catch (const InputError& e) {
    return e.messages();
  }
  ADD_FAILURE() << "no InputError";
  return {};
}

void expect_single_error(const std::vector<std::string>& lines, const std::string& expected) {
  const auto errs = errors_for(lines);
  ASSERT_EQ(errs.size(), 1u);
  EXPECT_NE(errs[0].find(expected), std::string::npos) << "got: " << errs[0] << "\nexpected to contain: " << expected;
}

TEST(EvalEstimates, ReadsEstimatesStepsAndCountsOtherEvents) {
  const auto f = test::parse_lines({
      R"({"type":"audio_detection","device":"A","frame":1.0})",
      "",
      test::estimate_line("tum", "A", "relative", "B", 1.5, {1, 2, 3}, {{"std_m", 0.2}, {"los", false}}),
      test::estimate_line("amil", "P", "player_start", "L1", 2.0, {nullptr, nullptr}, {{"direction_rad", 0.5}}),
      test::step_line("W1", 3.0, 0.7),
      R"({"type":"step","device":"W1","t_s":3.5,"stride_m":null,"frequency_hz":null})",
      R"({"type":"future_event","x":1})",
      "   ",
  });
  EXPECT_EQ(f.lines, 6u);
  ASSERT_EQ(f.estimates.size(), 2u);
  const EstimateRecord& a = f.estimates[0];
  EXPECT_EQ(a.plugin, "tum");
  EXPECT_EQ(a.reference, "A");
  EXPECT_EQ(a.frame, "relative");
  EXPECT_EQ(a.target, "B");
  EXPECT_EQ(a.dims, 3);
  EXPECT_DOUBLE_EQ(a.position_m[2], 3.0);
  EXPECT_DOUBLE_EQ(a.std_m, 0.2);
  EXPECT_TRUE(std::isnan(a.distance_m));
  ASSERT_TRUE(a.los.has_value());
  EXPECT_FALSE(*a.los);
  EXPECT_EQ(a.line, 3);
  EXPECT_TRUE(a.has_position());
  const EstimateRecord& b = f.estimates[1];
  EXPECT_EQ(b.dims, 2);
  EXPECT_FALSE(b.has_position());
  EXPECT_DOUBLE_EQ(b.direction_rad, 0.5);
  ASSERT_EQ(f.steps.size(), 2u);
  EXPECT_DOUBLE_EQ(f.steps[0].stride_m, 0.7);
  EXPECT_TRUE(std::isnan(f.steps[1].stride_m));
  EXPECT_EQ(f.steps[1].line, 6);
  EXPECT_EQ(f.other_events.at("audio_detection"), 1u);
  EXPECT_EQ(f.other_events.at("future_event"), 1u);
}

TEST(EvalEstimates, AcceptsCrLfLineEnds) {
  const auto f = test::parse_lines({test::estimate_line("x", "", "world", "A", 1.0, {1, 2}) + "\r"});
  EXPECT_EQ(f.estimates.size(), 1u);
}

TEST(EvalEstimates, NotJsonNamesLineAndColumn) {
  expect_single_error({test::step_line("W", 1, 0.7), R"({"type":"estimate", "plugin": tum})"},
                      "run.jsonl:2:32: not valid JSON: syntax error");
}

// Found by tests/fuzz (the same bug in amil::decode): nlohmann throws out_of_range, not parse_error,
// for a number beyond double; it escaped and aborted `locus eval`.
TEST(EvalEstimates, NumberBeyondDoubleIsAnErrorNotACrash) {
  expect_single_error({R"({"type":"estimate","plugin":"a","t_s":2.791e30851247})"},
                      "run.jsonl:1:1: not valid JSON: number overflow");
}

TEST(EvalEstimates, TruncatedLine) {
  expect_single_error({R"({"type":"estimate","plugin":"a")"}, "run.jsonl:1:");
  expect_single_error({R"({"type":"estimate","plugin":"a")"}, "not valid JSON");
}

TEST(EvalEstimates, NotAnObject) { expect_single_error({"[1,2,3]"}, "run.jsonl:1:1: expected a JSON object (one event per line), got an array"); }

TEST(EvalEstimates, MissingType) { expect_single_error({R"({"plugin":"a"})"}, "run.jsonl:1:1: missing string key 'type'"); }

TEST(EvalEstimates, MissingKey) {
  expect_single_error({R"({"type":"estimate","plugin":"p","reference":"","frame":"world","t_s":1,"position_m":[1,2]})"},
                      "run.jsonl:1:1: estimate event: missing key 'target' (expected a string)");
}

TEST(EvalEstimates, WrongTypeNamesTheKeyColumn) {
  const std::string line = R"({"type":"estimate","plugin":"p","reference":"","frame":"world","target":"A","t_s":"1.0","position_m":[1,2]})";
  const auto col = line.find("\"t_s\"") + 1;
  expect_single_error({line}, "run.jsonl:1:" + std::to_string(col) + ": estimate event: key 't_s': expected a number, got a string");
}

TEST(EvalEstimates, NullTime) {
  expect_single_error({R"({"type":"estimate","plugin":"p","reference":"","frame":"world","target":"A","t_s":null,"position_m":[1,2]})"},
                      "key 't_s': expected a number, got null");
}

TEST(EvalEstimates, PositionOfWrongLength) {
  expect_single_error({test::estimate_line("p", "", "world", "A", 1, {1, 2, 3, 4})},
                      "key 'position_m': expected an array of 2 or 3 numbers (or nulls), got an array of 4");
}

TEST(EvalEstimates, PositionElementNotANumber) {
  expect_single_error({R"({"type":"estimate","plugin":"p","reference":"","frame":"world","target":"A","t_s":1,"position_m":[1,"2"]})"},
                      "key 'position_m': element 1 is a string, expected a number or null");
}

TEST(EvalEstimates, EmptyTarget) {
  expect_single_error({test::estimate_line("p", "", "world", "", 1, {1, 2})}, "key 'target': expected a non-empty string");
}

TEST(EvalEstimates, LosNotBoolean) {
  expect_single_error({test::estimate_line("p", "", "world", "A", 1, {1, 2}, {{"los", 1}})},
                      "key 'los': expected true, false or null, got a number");
}

TEST(EvalEstimates, StepWithoutDevice) {
  expect_single_error({R"({"type":"step","t_s":1.0,"stride_m":0.7})"}, "run.jsonl:1:1: step event: missing key 'device'");
}

TEST(EvalEstimates, ListsEveryMalformedLineUpTo50) {
  std::vector<std::string> lines;
  for (int i = 0; i < 60; ++i) lines.push_back(i % 2 ? "{" : test::step_line("W", i, 0.7));
  const auto errs = errors_for(lines);
  ASSERT_EQ(errs.size(), 30u);
  EXPECT_NE(errs[0].find("run.jsonl:2:"), std::string::npos);
  EXPECT_NE(errs[29].find("run.jsonl:60:"), std::string::npos);
  lines.clear();
  for (int i = 0; i < 70; ++i) lines.push_back("nope");
  const auto many = errors_for(lines);
  ASSERT_EQ(many.size(), 51u);
  EXPECT_NE(many.back().find("... and 20 more malformed lines"), std::string::npos);
}

TEST(EvalEstimates, MissingFile) {
  try {
    read_estimates("/nonexistent/est.jsonl");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/est.jsonl: cannot open"), std::string::npos);
  }
}

}  // namespace
}  // namespace locus::eval
