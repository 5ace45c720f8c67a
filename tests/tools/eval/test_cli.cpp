// `locus eval` end to end: a scene directory on disk (scene.yaml + truth.csv), an estimates file,
// the command line through CLI11, the exit status (0 / 4 / 2 / 1), the table and the JSON output.
#include <gtest/gtest.h>
#include <CLI/CLI.hpp>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <unistd.h>

#include "eval/cli.hpp"
#include "eval_test_support.hpp"
#include "locus/eval/report.hpp"

namespace locus::eval {
namespace {

namespace fs = std::filesystem;
using test::estimate_line;

class EvalCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("locus_eval_" + std::to_string(::getpid()) + "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "P");
    fs::create_directories(dir_ / "Q");
    std::ofstream(dir_ / "P" / "audio.wav").put('\0');  // load_scene checks that streams exist; not read
    std::ofstream(dir_ / "Q" / "audio.wav").put('\0');
    write(dir_ / "scene.yaml", R"(format: locus-scene/1
name: eval-cli
sample_rate: 44100
speed_of_sound: 343.2
environment: {family: spyloc}
devices:
  - id: P
    mics: [[0.0, 0.0, 0.0]]
    audio: P/audio.wav
  - id: Q
    mics: [[0.0, 0.0, 0.0]]
    audio: Q/audio.wav
emitters:
  - id: B1
    emits: [{type: multitone, tones_hz: [18000, 18500], duration: 0.05}]
    anchor: {position: [0.0, 0.0, 2.5]}
truth:
  clocks:
    P: {offset_s: 0.25, skew_ppm: 50.0}
  trajectories: truth.csv
)");
    // P walks along x at 1 m/s for 10 s; Q stands at (0, 5).
    write(dir_ / "truth.csv",
          "t,id,x,y,z,qw,qx,qy,qz\n"
          "0,P,0,0,0,1,0,0,0\n"
          "0,Q,0,5,0,1,0,0,0\n"
          "0,B1,0,0,2.5,1,0,0,0\n"
          "10,P,10,0,0,1,0,0,0\n");
  }
  void TearDown() override { fs::remove_all(dir_); }

  static void write(const fs::path& p, const std::string& text) {
    std::ofstream f(p);
    f << text;
  }
  static std::string read(const fs::path& p) {
    std::ifstream f(p);
    std::stringstream ss;
    ss << f.rdbuf();
    return ss.str();
  }

  /// Estimates: P at true 2, 4, 6 s with 0.3 m error (stamped on P's clock); Q with 0.1 m error.
  std::string good_estimates(bool with_q = true) {
    const ClockModel p{0.25, 50.0};
    std::ostringstream os;
    for (double t : {2.0, 4.0, 6.0}) os << estimate_line("spyloc", "", "world", "P", p.local_from_true(t), {t, 0.3}) << "\n";
    if (with_q) os << estimate_line("spyloc", "", "world", "Q", 3.0, {0.1, 5.0}) << "\n";
    const fs::path path = dir_ / "est.jsonl";
    write(path, os.str());
    return path.string();
  }

  /// Runs `locus eval ARGS` through the real CLI11 wiring; captures nothing (prints to the console).
  static int run_cli(std::vector<std::string> args) {
    CLI::App app{"test"};
    app.require_subcommand(1);
    app::Subcommand sub = app::add_eval_command(app);
    args.insert(args.begin(), "locus");
    std::vector<const char*> argv;
    for (const auto& a : args) argv.push_back(a.c_str());
    try {
      app.parse(static_cast<int>(argv.size()), const_cast<char**>(argv.data()));
    } catch (const CLI::ParseError& e) {
      return app.exit(e) == 0 ? 0 : kExitBadInput;
    }
    return sub.run();
  }

  int run(EvalCommand cmd, std::string* out_text = nullptr, std::string* err_text = nullptr) {
    std::ostringstream out, err;
    const int code = run_eval(cmd, out, err);
    if (out_text) *out_text = out.str();
    if (err_text) *err_text = err.str();
    return code;
  }

  EvalCommand command(const std::string& estimates) {
    EvalCommand c;
    c.scene_dir = dir_.string();
    c.estimates_path = estimates;
    return c;
  }

  fs::path dir_;
};

TEST_F(EvalCli, PassingThresholdsExitZeroAndPrintTheTable) {
  EvalCommand c = command(good_estimates());
  c.thresholds = {{"max-mean-error-m", 0.3}, {"min-located-fraction", 1.0}, {"max-p90-error-m", 0.31}};
  std::string out, err;
  EXPECT_EQ(run(c, &out, &err), kExitOk) << out << err;
  EXPECT_NE(out.find("== spyloc  metric spyloc"), std::string::npos) << out;
  EXPECT_NE(out.find("mean_error_m = 0.250"), std::string::npos) << out;  // (3·0.3 + 0.1) / 4
  EXPECT_NE(out.find("PASS  spyloc: mean_error_m"), std::string::npos) << out;
  EXPECT_EQ(out.find("FAIL"), std::string::npos) << out;
}

TEST_F(EvalCli, MissedThresholdExitsFour) {
  EvalCommand c = command(good_estimates());
  c.thresholds = {{"max-mean-error-m", 0.2}};
  std::string out, err;
  EXPECT_EQ(run(c, &out, &err), kExitThresholdMissed);
  EXPECT_NE(out.find("FAIL  spyloc: mean_error_m = 0.250 <= 0.2"), std::string::npos) << out;
  EXPECT_NE(err.find("a threshold was missed"), std::string::npos) << err;
}

TEST_F(EvalCli, MissingTargetIsReportedAndFailsTheLocatedFraction) {
  EvalCommand c = command(good_estimates(/*with_q=*/false));
  c.thresholds = {{"min-located-fraction", 1.0}};
  std::string out;
  EXPECT_EQ(run(c, &out), kExitThresholdMissed);
  EXPECT_NE(out.find("no estimate"), std::string::npos) << out;
  EXPECT_NE(out.find("target 'Q' was not located"), std::string::npos) << out;
  EXPECT_NE(out.find("located_fraction = 0.500"), std::string::npos) << out;
}

TEST_F(EvalCli, UnknownTargetsCanFailTheRun) {
  std::string path = good_estimates();
  std::ofstream(path, std::ios::app) << estimate_line("spyloc", "", "world", "nobody", 1.0, {0, 0}) << "\n";
  EvalCommand c = command(path);
  std::string out;
  EXPECT_EQ(run(c, &out), kExitOk);  // a warning by default
  EXPECT_NE(out.find("target 'nobody' (1 estimates, first at " + path + ":5)"), std::string::npos) << out;
  c.thresholds = {{"max-unknown-targets", 0}};
  EXPECT_EQ(run(c), kExitThresholdMissed);
}

TEST_F(EvalCli, MalformedEstimatesExitTwoNamingFileAndLine) {
  const fs::path path = dir_ / "bad.jsonl";
  write(path, estimate_line("spyloc", "", "world", "P", 1.0, {1, 0}) + "\n{\"type\": \"estimate\", \"plugin\": 7}\n");
  std::string out, err;
  EXPECT_EQ(run(command(path.string()), &out, &err), kExitBadInput);
  EXPECT_NE(err.find(path.string() + ":2:"), std::string::npos) << err;
  EXPECT_NE(err.find("key 'plugin': expected a string, got a number"), std::string::npos) << err;
  EXPECT_TRUE(out.empty());
}

TEST_F(EvalCli, ThresholdNoPluginReportsIsBadInput) {
  EvalCommand c = command(good_estimates());
  c.thresholds = {{"max-direction-error-deg", 5}};
  std::string err;
  EXPECT_EQ(run(c, nullptr, &err), kExitBadInput);
  EXPECT_NE(err.find("--max-direction-error-deg: no scored plugin reports 'mean_direction_error_deg' (scored: spyloc (spyloc))"),
            std::string::npos) << err;
}

TEST_F(EvalCli, NothingToScoreMissesEveryThreshold) {
  const fs::path path = dir_ / "empty.jsonl";
  write(path, test::step_line("P", 1.0, 0.7) + "\n");
  EvalCommand c = command(path.string());
  c.options.metric = "spyloc";  // no estimate: no group, so the threshold reports nothing
  c.thresholds = {{"max-mean-error-m", 1.0}};
  std::string err;
  EXPECT_EQ(run(c, nullptr, &err), kExitBadInput);
  EXPECT_NE(err.find("(scored: none)"), std::string::npos) << err;
}

TEST_F(EvalCli, SceneWithoutTruthIsBadInput) {
  std::string yaml = read(dir_ / "scene.yaml");
  write(dir_ / "scene.yaml", yaml.substr(0, yaml.find("truth:")));
  std::string err;
  EXPECT_EQ(run(command(good_estimates()), nullptr, &err), kExitBadInput);
  EXPECT_NE(err.find("scene.yaml: the scene has no `truth` section"), std::string::npos) << err;
}

TEST_F(EvalCli, BrokenTruthCsvIsBadInputWithLineAndColumn) {
  write(dir_ / "truth.csv", "t,id,x,y,z,qw,qx,qy,qz\n0,P,0,0,zero,1,0,0,0\n");
  std::string err;
  EXPECT_EQ(run(command(good_estimates()), nullptr, &err), kExitBadInput);
  EXPECT_NE(err.find("truth.csv:2:"), std::string::npos) << err;
}

TEST_F(EvalCli, JsonOutputCarriesTheSameResults) {
  EvalCommand c = command(good_estimates());
  c.json = true;
  c.json_output = (dir_ / "result.json").string();
  c.thresholds = {{"max-mean-error-m", 0.2}};
  std::string out;
  EXPECT_EQ(run(c, &out), kExitThresholdMissed);
  const auto j = nlohmann::json::parse(out);
  EXPECT_EQ(j["exit_code"], kExitThresholdMissed);
  EXPECT_FALSE(j["passed"].get<bool>());
  ASSERT_EQ(j["plugins"].size(), 1u);
  EXPECT_EQ(j["plugins"][0]["metric"], "spyloc");
  EXPECT_NEAR(j["plugins"][0]["summary"]["mean_error_m"].get<double>(), 0.25, 1e-9);
  EXPECT_EQ(j["plugins"][0]["summary"]["targets_expected"], 2);  // P and Q; the anchored beacon is not
  EXPECT_EQ(j["thresholds"][0]["option"], "--max-mean-error-m");
  std::ifstream f(c.json_output);
  EXPECT_EQ(nlohmann::json::parse(f), j);
}

TEST_F(EvalCli, ReadsTruthStepsAndTruthLosNextToTruthCsv) {
  // The simulator's extra truth files (tools/sim: truth_steps.csv with an extra column, truth_los.csv).
  write(dir_ / "truth_steps.csv", "t_true,id,stride_m,frequency_hz\n1.0,P,0.70,1.8\n1.5,P,0.72,1.8\n");
  write(dir_ / "truth_los.csv", "t_true,beacon,los\n0.5,B1,1\n5.0,B1,0\n");
  const ClockModel p{0.25, 50.0};
  const fs::path path = dir_ / "steps.jsonl";
  write(path, test::step_line("P", p.local_from_true(1.02), 0.75) + "\n" + test::step_line("P", p.local_from_true(1.49), 0.70) + "\n" +
                  estimate_line("spyloc", "", "world", "P", p.local_from_true(2.0), {2.0, 0.2}) + "\n" +
                  estimate_line("spyloc", "", "world", "P", p.local_from_true(6.0), {6.0, 0.6}) + "\n");
  EvalCommand c = command(path.string());
  c.json = true;
  std::string out;
  ASSERT_EQ(run(c, &out), kExitOk);
  auto j = nlohmann::json::parse(out);
  EXPECT_NEAR(j["plugins"][0]["summary"]["los_median_error_m"].get<double>(), 0.2, 1e-9);
  EXPECT_NEAR(j["plugins"][0]["summary"]["nlos_median_error_m"].get<double>(), 0.6, 1e-9);
  c.options.metric = "montage";
  ASSERT_EQ(run(c, &out), kExitOk);
  j = nlohmann::json::parse(out);
  EXPECT_EQ(j["plugins"][0]["summary"]["steps_matched"], 2);
  EXPECT_NEAR(j["plugins"][0]["summary"]["mean_stride_error_m"].get<double>(), 0.035, 1e-9);
  // A malformed extra truth file is bad input with its line and column.
  write(dir_ / "truth_steps.csv", "t_true,id,stride_m\n1.0,P,long\n");
  std::string err;
  EXPECT_EQ(run(c, nullptr, &err), kExitBadInput);
  EXPECT_NE(err.find("truth_steps.csv:2:"), std::string::npos) << err;
}

TEST_F(EvalCli, TheScenesFamilyPicksTheMetricWithoutItTheRunIsBadInput) {
  std::string yaml = read(dir_ / "scene.yaml");
  EXPECT_EQ(load_truth(dir_.string()).family, "spyloc");
  // A plugin named like another system is still scored by the scene's family.
  const fs::path path = dir_ / "named.jsonl";
  write(path, estimate_line("amil_tum", "", "world", "P", 1.0, {1, 0}) + "\n");
  std::string out;
  EXPECT_EQ(run(command(path.string()), &out), kExitOk);
  EXPECT_NE(out.find("== amil_tum  metric spyloc"), std::string::npos) << out;
  // No environment.family and no --metric: exit 2 with the scene file and the way out.
  const std::string nofamily = yaml.replace(yaml.find("environment: {family: spyloc}\n"), 30, "");
  write(dir_ / "scene.yaml", nofamily);
  EXPECT_EQ(load_truth(dir_.string()).family, "");
  std::string err;
  EXPECT_EQ(run(command(path.string()), nullptr, &err), kExitBadInput);
  EXPECT_NE(err.find((dir_ / "scene.yaml").string() + ": the scene names no family (environment.family) and no --metric was given"),
            std::string::npos) << err;
  EvalCommand c = command(path.string());
  c.options.metric = "position";
  EXPECT_EQ(run(c, &out), kExitOk);
  EXPECT_NE(out.find("== amil_tum  metric position"), std::string::npos) << out;
  // A family that is no name: file, line and column.
  write(dir_ / "scene.yaml", nofamily + "environment:\n  family: [a, b]\n");
  EXPECT_EQ(run(command(path.string()), nullptr, &err), kExitBadInput);
  EXPECT_NE(err.find("scene.yaml:"), std::string::npos) << err;
  EXPECT_NE(err.find("environment.family: expected the name of a system"), std::string::npos) << err;
}

TEST_F(EvalCli, CommandLineWiring) {
  const std::string est = good_estimates();
  EXPECT_EQ(run_cli({"eval", dir_.string(), est, "--max-mean-error-m", "0.3"}), kExitOk);
  EXPECT_EQ(run_cli({"eval", dir_.string(), est, "--max-mean-error-m", "0.2"}), kExitThresholdMissed);
  EXPECT_EQ(run_cli({"eval", dir_.string(), est, "--metric", "position", "--max-median-error-m", "0.3", "--json"}), kExitOk);
  EXPECT_EQ(run_cli({"eval", dir_.string(), est, "--metric", "gps"}), kExitBadInput);
  EXPECT_EQ(run_cli({"eval", dir_.string()}), kExitBadInput);
  EXPECT_EQ(run_cli({"eval", dir_.string(), (dir_ / "missing.jsonl").string()}), kExitBadInput);
  EXPECT_EQ(run_cli({"eval", dir_.string(), est, "--plugin", "other", "--max-mean-error-m", "1"}), kExitBadInput);
}

}  // namespace
}  // namespace locus::eval
