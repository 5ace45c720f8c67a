// link/auth/message_auth: what a receiver accepts and what it refuses, with explicit clocks.
#include "auth/message_auth.hpp"

#include <gtest/gtest.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

namespace locus::linkauth {
namespace {

namespace fs = std::filesystem;

const std::string kKey = "0123456789abcdef0123456789abcdef";
constexpr double kNow = 1.8e9;  // a unix time in 2027

TEST(MessageAuth, SignedMessageIsAcceptedOnceWithItsPayload) {
  MessageAuthenticator a(kKey, "board-a", 30.0);
  MessageAuthenticator b(kKey, "board-b", 30.0);
  const std::string wire = a.sign("amil/arrivals/L01", R"({"beep":3})", kNow);
  EXPECT_EQ(wire.rfind("LOCUS-HMAC1 board-a ", 0), 0u) << wire;
  const auto r = b.verify("amil/arrivals/L01", wire, kNow + 0.2);
  EXPECT_EQ(r.verdict, Verdict::Accepted);
  EXPECT_EQ(r.payload, R"({"beep":3})");
  EXPECT_EQ(r.sender, "board-a");
  // The same bytes again: a replay.
  EXPECT_EQ(b.verify("amil/arrivals/L01", wire, kNow + 0.3).verdict, Verdict::Replayed);
  const AuthCounts c = b.counts();
  EXPECT_EQ(c.accepted, 1u);
  EXPECT_EQ(c.replayed, 1u);
  EXPECT_EQ(c.rejected(), 1u);
}

TEST(MessageAuth, AlteredPayloadTopicOrHeaderFailsTheSignature) {
  MessageAuthenticator a(kKey, "board-a", 30.0);
  MessageAuthenticator b(kKey, "board-b", 30.0);
  const std::string wire = a.sign("amil/arrivals/L01", R"({"beep":3,"t":1.25})", kNow);
  std::string payload_changed = wire;
  payload_changed[payload_changed.size() - 2] = '6';
  EXPECT_EQ(b.verify("amil/arrivals/L01", payload_changed, kNow).verdict, Verdict::BadSignature);
  // Moved to another board's topic.
  EXPECT_EQ(b.verify("amil/arrivals/L02", wire, kNow).verdict, Verdict::BadSignature);
  // The sender name rewritten (same length).
  std::string sender_changed = wire;
  sender_changed.replace(sender_changed.find("board-a"), 7, "board-c");
  EXPECT_EQ(b.verify("amil/arrivals/L01", sender_changed, kNow).verdict, Verdict::BadSignature);
  // Another site's key.
  MessageAuthenticator other("another-site-key-0123456789", "board-a", 30.0);
  EXPECT_EQ(b.verify("amil/arrivals/L01", other.sign("amil/arrivals/L01", "{}", kNow), kNow).verdict,
            Verdict::BadSignature);
  EXPECT_EQ(b.counts().bad_signature, 4u);
  EXPECT_EQ(b.counts().accepted, 0u);
}

TEST(MessageAuth, UnsignedAndMalformedAreRefused) {
  MessageAuthenticator b(kKey, "board-b", 30.0);
  EXPECT_EQ(b.verify("t", R"({"beep":3})", kNow).verdict, Verdict::Unsigned);
  EXPECT_EQ(b.verify("t", "", kNow).verdict, Verdict::Unsigned);
  EXPECT_EQ(b.verify("t", "LOCUS-HMAC1 x\n{}", kNow).verdict, Verdict::Malformed);
  EXPECT_EQ(b.verify("t", "LOCUS-HMAC1 board-a 0011223344556677 1 1800000000000 zz\n{}", kNow).verdict,
            Verdict::Malformed);
  EXPECT_EQ(b.verify("t", "LOCUS-HMAC1 board-a 0011223344556677 -1 1800000000000 " + std::string(64, 'a') + "\n{}",
                     kNow).verdict,
            Verdict::Malformed);
  EXPECT_EQ(b.verify("t", "LOCUS-HMAC1 no-newline", kNow).verdict, Verdict::Malformed);
  EXPECT_EQ(b.counts().unsigned_messages, 2u);
  EXPECT_EQ(b.counts().malformed, 4u);
}

TEST(MessageAuth, MessagesOutsideTheTimeWindowAreStale) {
  MessageAuthenticator a(kKey, "board-a", 30.0);
  MessageAuthenticator b(kKey, "board-b", 30.0);
  EXPECT_EQ(b.verify("t", a.sign("t", "{}", kNow - 31.0), kNow).verdict, Verdict::Stale);
  EXPECT_EQ(b.verify("t", a.sign("t", "{}", kNow + 31.0), kNow).verdict, Verdict::Stale);
  EXPECT_EQ(b.verify("t", a.sign("t", "{}", kNow - 29.0), kNow).verdict, Verdict::Accepted);
  EXPECT_EQ(b.counts().stale, 2u);
}

TEST(MessageAuth, OutOfOrderWithinTheWindowIsAcceptedEachOnce) {
  MessageAuthenticator a(kKey, "board-a", 30.0);
  MessageAuthenticator b(kKey, "board-b", 30.0);
  std::vector<std::string> wires;
  for (int i = 0; i < 2000; ++i) wires.push_back(a.sign("t", std::to_string(i), kNow));
  // Newest first for a few, then the rest in order: every one accepted exactly once.
  for (int i : {5, 3, 4, 0, 1, 2}) EXPECT_EQ(b.verify("t", wires[i], kNow).verdict, Verdict::Accepted) << i;
  for (int i = 6; i < 2000; ++i) ASSERT_EQ(b.verify("t", wires[i], kNow).verdict, Verdict::Accepted) << i;
  for (int i : {0, 1500, 1999}) EXPECT_EQ(b.verify("t", wires[i], kNow).verdict, Verdict::Replayed) << i;
  // A gap larger than the window, then an old one behind it: refused (cannot be told from a replay).
  for (int i = 0; i < 1100; ++i) a.sign("t", "skipped", kNow);
  EXPECT_EQ(b.verify("t", a.sign("t", "late", kNow), kNow).verdict, Verdict::Accepted);
  EXPECT_EQ(b.counts().replayed, 3u);
}

TEST(MessageAuth, ARestartedSenderStartsAFreshSequence) {
  MessageAuthenticator b(kKey, "board-b", 30.0);
  MessageAuthenticator first(kKey, "board-a", 30.0);
  const std::string w1 = first.sign("t", "{}", kNow);
  EXPECT_EQ(b.verify("t", w1, kNow).verdict, Verdict::Accepted);
  MessageAuthenticator restarted(kKey, "board-a", 30.0);  // new nonce, seq starts at 1 again
  EXPECT_EQ(b.verify("t", restarted.sign("t", "{}", kNow + 1), kNow + 1).verdict, Verdict::Accepted);
  EXPECT_EQ(b.verify("t", w1, kNow + 2).verdict, Verdict::Replayed);
}

TEST(MessageAuth, BadConstructionIsRefusedNamingWhat) {
  EXPECT_THROW(MessageAuthenticator("short", "a", 30.0), AuthError);
  EXPECT_THROW(MessageAuthenticator(kKey, "", 30.0), AuthError);
  EXPECT_THROW(MessageAuthenticator(kKey, "has space", 30.0), AuthError);
  EXPECT_THROW(MessageAuthenticator(kKey, "a", 0.0), AuthError);
}

class KeyFile : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string tmpl = (fs::temp_directory_path() / "locus-key-XXXXXX").string();
    ASSERT_NE(::mkdtemp(tmpl.data()), nullptr);
    dir_ = tmpl;
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  fs::path write(const std::string& name, const std::string& content, mode_t mode) {
    const fs::path p = dir_ / name;
    std::ofstream(p) << content;
    ::chmod(p.c_str(), mode);
    return p;
  }
  static std::string error_of(const fs::path& p) {
    try {
      load_key_file(p.string(), "mqtt link: auth_key_file");
    } catch (const AuthError& e) {
      return e.what();
    }
    return "";
  }
  fs::path dir_;
};

TEST_F(KeyFile, ReadsTheKeyWithoutTrailingNewline) {
  const fs::path p = write("site.key", kKey + "\n", 0600);
  EXPECT_EQ(load_key_file(p.string(), "k"), kKey);
}

TEST_F(KeyFile, RefusesAKeyOthersCanReadWithTheFix) {
  const fs::path p = write("open.key", kKey, 0644);
  const std::string e = error_of(p);
  EXPECT_NE(e.find("mqtt link: auth_key_file: key file " + p.string() + " is readable or writable by every user"),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("chmod o-rw " + p.string()), std::string::npos) << e;
}

TEST_F(KeyFile, RefusesShortMissingAndDirectory) {
  const std::string short_err = error_of(write("short.key", "abc\n", 0600));
  EXPECT_NE(short_err.find("holds 3 bytes; expected at least 16"), std::string::npos) << short_err;
  EXPECT_NE(short_err.find("openssl rand -hex 32"), std::string::npos) << short_err;
  const std::string missing = error_of(dir_ / "none.key");
  EXPECT_NE(missing.find("cannot read key file " + (dir_ / "none.key").string()), std::string::npos) << missing;
  EXPECT_NE(error_of(dir_).find("not a regular file"), std::string::npos);
}

}  // namespace
}  // namespace locus::linkauth
