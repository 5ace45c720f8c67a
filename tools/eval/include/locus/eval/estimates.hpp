// Reads the JSON-lines output of a pipeline (docs/events.md) for scoring: the `estimate` and `step`
// events; every other event type is counted and otherwise ignored. Strict: a line that is not a JSON
// object, has no string `type`, or an estimate/step whose keys have the wrong type is an error naming
// file:line:column (column = 1-based byte in the line) and what was expected. Keys the reader does
// not know are ignored (events.md: keys are only ever added).
#pragma once

#include <array>
#include <cstddef>
#include <istream>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace locus::eval {

/// One `estimate` line. Unknown values (JSON null) are NaN.
struct EstimateRecord {
  std::string plugin;
  std::string reference;               ///< "" = world
  std::string frame;
  std::string target;
  double t_s = 0.0;                    ///< on the reference's clock (docs/eval.md, "Time")
  std::array<double, 3> position_m{};  ///< NaN where null; z = 0 when dims == 2
  int dims = 2;                        ///< length of position_m (2 or 3)
  double direction_rad = 0.0;
  double distance_m = 0.0;
  double std_m = 0.0;
  double confidence = 0.0;
  double direction_std_rad = 0.0;      ///< NaN when null or absent
  double distance_std_m = 0.0;         ///< NaN when null or absent
  std::vector<std::string> flags;      ///< optional `flags` list (docs/events.md)
  std::optional<bool> los;             ///< optional extra key `los` (SpyLoc: line of sight)
  int line = 0;                        ///< 1-based line in the file

  /// All `dims` position components are known.
  bool has_position() const noexcept;
};

/// One `step` line (docs/events.md).
struct StepRecord {
  std::string device;
  std::string detector;
  double t_s = 0.0;                    ///< device-local time of the heel strike
  double stride_m = 0.0;               ///< NaN when null
  int line = 0;
};

struct EstimatesFile {
  std::string path;
  std::vector<EstimateRecord> estimates;
  std::vector<StepRecord> steps;
  std::size_t lines = 0;               ///< non-blank lines
  std::map<std::string, std::size_t> other_events;  ///< count per type of the other lines
};

/// Parses a JSON-lines stream; `name` is used in messages. Collects every malformed line (the first
/// 50 are listed) and throws InputError when there is at least one. Blank lines are allowed.
EstimatesFile parse_estimates(std::istream& in, const std::string& name);
/// Opens and parses a file ("-" = stdin). InputError when it cannot be opened.
EstimatesFile read_estimates(const std::string& path);

}  // namespace locus::eval
