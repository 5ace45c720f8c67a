// Errors of the scorer. InputError = the inputs (scene, truth files, estimates file, options) are
// malformed or inconsistent: `locus eval` exits 2 and prints every message. Anything else thrown is a
// failure of the tool itself (exit 1).
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

namespace locus::eval {

/// One or more input problems, each already formatted as "file:line:column: what was expected"
/// (or "file: ..." / "--option: ..." when there is no line). what() joins them with newlines.
class InputError : public std::runtime_error {
 public:
  explicit InputError(std::vector<std::string> messages);
  explicit InputError(const std::string& message) : InputError(std::vector<std::string>{message}) {}
  const std::vector<std::string>& messages() const noexcept { return messages_; }

 private:
  std::vector<std::string> messages_;
};

}  // namespace locus::eval
