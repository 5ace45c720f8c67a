// Events as JSON lines (one object per line), the output of locusd and `locus replay`.
// The shape of every event type is documented in docs/events.md; keep the two in step.
#pragma once

#include <cstdio>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>

#include "locus/events.hpp"

namespace locus {

/// {"type": "<event_type_name>", ...fields}; NaN fields are written as null.
nlohmann::ordered_json event_to_json(const Event& event);

/// Writes events as JSON lines to a file or stdout ("-"). Each line is flushed when written, so a
/// stop (Ctrl-C, SIGTERM) loses nothing already accepted. [main] (the dispatcher thread).
class JsonLinesWriter {
 public:
  /// Throws std::runtime_error naming the path if it cannot be opened.
  explicit JsonLinesWriter(const std::string& path);
  ~JsonLinesWriter();
  JsonLinesWriter(const JsonLinesWriter&) = delete;
  JsonLinesWriter& operator=(const JsonLinesWriter&) = delete;

  void write(const Event& event);
  void write(const nlohmann::ordered_json& object);
  void flush();
  std::uint64_t lines() const noexcept { return lines_; }

 private:
  std::FILE* file_ = nullptr;
  bool owned_ = false;
  std::string path_;
  std::uint64_t lines_ = 0;
};

}  // namespace locus
