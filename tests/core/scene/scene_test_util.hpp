// Helpers for the scene format tests: a per-test temporary directory, raw file writing, a WAV builder
// that writes headers byte by byte (independent of the code under test) and error-message capture.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <unistd.h>

#include "locus/scene/scene.hpp"

namespace locus::scene::test {

/// A fresh directory under the system temp dir, removed at destruction.
class TempDir {
 public:
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    std::string name = std::string("locus-scene-") + (info ? std::string(info->test_suite_name()) + "-" + info->name() : "x");
    for (char& c : name)
      if (c == '/') c = '_';
    path_ = std::filesystem::temp_directory_path() / (name + "-" + std::to_string(::getpid()));
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  std::string str() const { return path_.string(); }
  std::string operator/(const std::string& rel) const { return (path_ / rel).string(); }

 private:
  std::filesystem::path path_;
};

inline void write_file(const std::string& path, const std::string& bytes) {
  std::filesystem::create_directories(std::filesystem::path(path).parent_path());
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

inline std::string read_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

inline void put16(std::string& s, unsigned v) {
  s.push_back(char(v & 0xFF));
  s.push_back(char((v >> 8) & 0xFF));
}
inline void put32(std::string& s, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) s.push_back(char((v >> (8 * i)) & 0xFF));
}

/// Byte-level WAV description for hand-built files.
struct RawWav {
  unsigned tag = 1;           ///< 1 PCM, 3 float, 0xFFFE extensible
  unsigned sub_tag = 1;       ///< extensible sub-format
  unsigned channels = 1;
  std::uint32_t rate = 48000;
  unsigned bits = 16;
  int block_align = -1;       ///< -1 = channels*bits/8
  std::string extra_chunks;   ///< raw chunks between fmt and data
  std::string data;           ///< sample bytes
  long long declared_data = -1;  ///< -1 = data.size()
};

/// Builds the bytes of a WAV file: RIFF, WAVE, fmt (16 or 40 bytes), extra chunks, data.
inline std::string build_wav(const RawWav& w) {
  std::string fmt;
  put16(fmt, w.tag);
  put16(fmt, w.channels);
  put32(fmt, w.rate);
  const unsigned align = w.block_align >= 0 ? unsigned(w.block_align) : w.channels * w.bits / 8;
  put32(fmt, w.rate * align);
  put16(fmt, align);
  put16(fmt, w.bits);
  if (w.tag == 0xFFFE) {
    put16(fmt, 22);
    put16(fmt, w.bits);
    put32(fmt, 0);
    put16(fmt, w.sub_tag);
    const unsigned char tail[14] = {0x00, 0x00, 0x00, 0x00, 0x10, 0x00, 0x80, 0x00, 0x00, 0xAA, 0x00, 0x38, 0x9B, 0x71};
    fmt.append(reinterpret_cast<const char*>(tail), 14);
  }
  std::string body = "WAVE";
  body += "fmt ";
  put32(body, std::uint32_t(fmt.size()));
  body += fmt;
  body += w.extra_chunks;
  body += "data";
  put32(body, std::uint32_t(w.declared_data >= 0 ? std::uint64_t(w.declared_data) : w.data.size()));
  body += w.data;
  std::string out = "RIFF";
  put32(out, std::uint32_t(body.size()));
  return out + body;
}

/// Runs `f`, expects a SceneError, returns its what() ("" and a test failure when nothing thrown).
template <class F>
std::string scene_error(F&& f) {
  try {
    f();
  } catch (const SceneError& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected SceneError, got std::exception: " << e.what();
    return "";
  }
  ADD_FAILURE() << "expected SceneError, nothing was thrown";
  return "";
}

}  // namespace locus::scene::test
