// Events as JSON lines (one object per line), the output of locusd and `locus replay`.
// The shape of every event type is documented in docs/events.md; keep the two in step.
#pragma once

#include <cstdint>
#include <cstdio>
#include <functional>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>

#include "locus/events.hpp"

namespace locus {

/// {"type": "<event_type_name>", ...fields}; NaN fields are written as null.
nlohmann::ordered_json event_to_json(const Event& event);

/// Writes events as JSON lines to a file or stdout ("-"). Each line is flushed when written, so a
/// stop (Ctrl-C, SIGTERM) loses nothing already accepted. [main] (the dispatcher thread).
///
/// A failed write (a consumer that went away: EPIPE with SIGPIPE ignored, as locusd does; a full disk:
/// ENOSPC) never ends the process and never passes silently: the line is counted in lines_failed(),
/// the first failure and the recovery after a run of failures go to `on_problem` (the host logs them),
/// and every later line is tried again (a disk that has room again gets the next lines).
class JsonLinesWriter {
 public:
  /// Receives "output '<path>': ..." messages; `error` true for a failure, false for a recovery.
  using ProblemHandler = std::function<void(const std::string& message, bool error)>;

  /// Throws std::runtime_error naming the path if it cannot be opened.
  explicit JsonLinesWriter(const std::string& path, ProblemHandler on_problem = {});
  ~JsonLinesWriter();
  JsonLinesWriter(const JsonLinesWriter&) = delete;
  JsonLinesWriter& operator=(const JsonLinesWriter&) = delete;

  void write(const Event& event);
  void write(const nlohmann::ordered_json& object);
  void flush();
  /// Lines written completely.
  std::uint64_t lines() const noexcept { return lines_; }
  /// Lines that could not be written (possibly in part).
  std::uint64_t lines_failed() const noexcept { return lines_failed_; }
  /// The last write error ("" if none), e.g. "Broken pipe".
  const std::string& error() const noexcept { return error_; }
  const std::string& path() const noexcept { return path_; }

 private:
  std::FILE* file_ = nullptr;
  bool owned_ = false;
  std::string path_;
  ProblemHandler on_problem_;
  std::uint64_t lines_ = 0;
  std::uint64_t lines_failed_ = 0;
  std::uint64_t failing_run_ = 0;  // consecutive failed lines (0 = writing fine)
  std::string error_;
};

}  // namespace locus
