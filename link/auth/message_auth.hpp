// Link message authenticity beyond the broker: a shared-key HMAC-SHA256 on every link message, with
// replay protection.
//
// Broker credentials and ACLs (docs/mqtt.md) decide who may publish where; they do not stop a board
// whose password leaked, a misconfigured bridge, or anyone who can inject into an unencrypted broker
// connection from publishing a "beep report" that moves every estimate. With `auth_key_file` set, each
// message carries a header line that binds the sender, a per-process nonce, a sequence number and the
// send time to the topic and payload under the site's key:
//
//   LOCUS-HMAC1 <sender> <nonce: 16 hex> <seq> <time_ms> <HMAC-SHA256: 64 hex>\n<payload bytes>
//
// where the MAC covers "LOCUS-HMAC1\n<topic>\n<sender>\n<nonce>\n<seq>\n<time_ms>\n<payload>". A receiver
// accepts a message once: a forged or altered one fails the MAC, a message whose time is more than
// window_s from the receiver's clock is stale (boards keep NTP time), and a (sender, nonce, seq) seen
// before is a replay (a sliding 1024-bit window per sender process, as IPsec's anti-replay window, so
// the state is bounded and out-of-order delivery within the window is accepted). Every rejection is
// counted by reason. The MAC is OpenSSL's (libcrypto); nothing here is hand-rolled crypto.
//
// Pure and single-purpose: MqttLink calls sign() on publish and verify() on arrival; the unit tests call
// them directly with explicit times.
#pragma once

#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>

namespace locus::linkauth {

/// Bad key file or options; the message names the file or key and what was expected.
class AuthError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Why a message was accepted or not.
enum class Verdict { Accepted, Unsigned, Malformed, BadSignature, Stale, Replayed };
const char* verdict_name(Verdict v) noexcept;

/// The rejection counters (and accepted messages), by verdict.
struct AuthCounts {
  std::uint64_t accepted = 0;
  std::uint64_t unsigned_messages = 0;  ///< no header: sent by a link without the key
  std::uint64_t malformed = 0;          ///< a header that does not parse
  std::uint64_t bad_signature = 0;      ///< forged or altered (or another site's key)
  std::uint64_t stale = 0;              ///< time outside the window
  std::uint64_t replayed = 0;           ///< (sender, nonce, seq) accepted before, or behind the window
  std::uint64_t rejected() const noexcept {
    return unsigned_messages + malformed + bad_signature + stale + replayed;
  }
};

/// [main] Reads a shared key file: at least 16 bytes after trailing whitespace is stripped (e.g. the
/// output of `openssl rand -hex 32`). Refuses a file that others may read (mode & 0004) or write
/// (mode & 0002), naming the chmod that fixes it. `what` prefixes messages ("mqtt link: auth_key_file").
std::string load_key_file(const std::string& path, std::string_view what);

class MessageAuthenticator {
 public:
  static constexpr std::string_view kMagic = "LOCUS-HMAC1";
  static constexpr std::uint64_t kReplayWindow = 1024;  ///< sequence numbers tracked per sender process

  /// `sender`: this node's name in the header ([A-Za-z0-9_.:-], 1-64 chars); `window_s` > 0. The nonce
  /// is drawn from the OS (RAND_bytes) so that a restarted sender starts a fresh sequence. Throws
  /// AuthError for a short key, a bad sender name or window.
  MessageAuthenticator(std::string key, std::string sender, double window_s);

  /// [any thread] The wire bytes for `payload` published on `topic` at `now_unix_s`.
  std::string sign(std::string_view topic, std::string_view payload, double now_unix_s);

  struct Result {
    Verdict verdict = Verdict::Malformed;
    std::string payload;  ///< the original payload (Accepted only)
    std::string sender;   ///< as the header says (empty when it does not parse)
  };
  /// [any thread] Checks `wire` received on `topic` at `now_unix_s` and counts the verdict. Accepted
  /// messages are remembered so that the same one is a replay next time.
  Result verify(std::string_view topic, std::string_view wire, double now_unix_s);

  AuthCounts counts() const;
  const std::string& sender() const noexcept { return sender_; }
  double window_s() const noexcept { return window_s_; }

 private:
  struct Window {  // one sender process (sender, nonce)
    std::uint64_t highest = 0;
    std::uint64_t bits[kReplayWindow / 64] = {};  // bit (seq % kReplayWindow) set = seen, for seq > highest - window
    bool any = false;
    double last_seen_unix_s = 0;
  };
  std::string mac_hex(std::string_view topic, std::string_view sender, std::string_view nonce, std::uint64_t seq,
                      std::int64_t time_ms, std::string_view payload) const;
  bool accept_sequence(const std::string& who, std::uint64_t seq, double now_unix_s);  // mutex_ held

  std::string key_;
  std::string sender_;
  std::string nonce_;  // 16 hex digits
  double window_s_;
  mutable std::mutex mutex_;
  std::uint64_t next_seq_ = 1;
  std::map<std::string, Window> windows_;  // "sender nonce" -> window
  double last_prune_unix_s_ = 0;
  AuthCounts counts_;
};

}  // namespace locus::linkauth
