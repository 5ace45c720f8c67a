#include "auth/message_auth.hpp"

#include <openssl/crypto.h>
#include <openssl/hmac.h>
#include <openssl/rand.h>
#include <sys/stat.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>

namespace locus::linkauth {

namespace {

constexpr std::size_t kMinKeyBytes = 16;

std::string to_hex(const unsigned char* p, std::size_t n) {
  static const char* digits = "0123456789abcdef";
  std::string s(2 * n, '0');
  for (std::size_t i = 0; i < n; ++i) {
    s[2 * i] = digits[p[i] >> 4];
    s[2 * i + 1] = digits[p[i] & 15];
  }
  return s;
}

bool is_hex(std::string_view s) {
  for (char c : s) {
    if (!((c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'))) return false;
  }
  return true;
}

bool valid_sender(std::string_view s) {
  if (s.empty() || s.size() > 64) return false;
  for (char c : s) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
                    c == '.' || c == ':' || c == '-';
    if (!ok) return false;
  }
  return true;
}

template <typename T>
bool parse_int(std::string_view s, T& out) {
  if (s.empty()) return false;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  return ec == std::errc() && end == s.data() + s.size();
}

}  // namespace

const char* verdict_name(Verdict v) noexcept {
  switch (v) {
    case Verdict::Accepted: return "accepted";
    case Verdict::Unsigned: return "unsigned";
    case Verdict::Malformed: return "malformed";
    case Verdict::BadSignature: return "bad signature";
    case Verdict::Stale: return "stale";
    case Verdict::Replayed: return "replayed";
  }
  return "?";
}

std::string load_key_file(const std::string& path, std::string_view what) {
  const std::string w(what);
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    throw AuthError(w + ": cannot read key file " + path + ": " + std::strerror(errno));
  }
  if (!S_ISREG(st.st_mode)) throw AuthError(w + ": key file " + path + " is not a regular file");
  if ((st.st_mode & (S_IROTH | S_IWOTH)) != 0) {
    char mode[8];
    std::snprintf(mode, sizeof mode, "%04o", static_cast<unsigned>(st.st_mode & 07777));
    throw AuthError(w + ": key file " + path + " is readable or writable by every user (mode " + mode +
                    "): anyone on this board could sign link messages; refused (fix: chmod o-rw " + path + ")");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) throw AuthError(w + ": cannot read key file " + path);
  std::stringstream ss;
  ss << in.rdbuf();
  std::string key = ss.str();
  while (!key.empty() && (key.back() == '\n' || key.back() == '\r' || key.back() == ' ' || key.back() == '\t')) {
    key.pop_back();
  }
  if (key.size() < kMinKeyBytes) {
    throw AuthError(w + ": key file " + path + " holds " + std::to_string(key.size()) + " bytes; expected at least " +
                    std::to_string(kMinKeyBytes) + " (make one with: openssl rand -hex 32 > " + path + ")");
  }
  return key;
}

MessageAuthenticator::MessageAuthenticator(std::string key, std::string sender, double window_s)
    : key_(std::move(key)), sender_(std::move(sender)), window_s_(window_s) {
  if (key_.size() < kMinKeyBytes) {
    throw AuthError("link authentication: the key has " + std::to_string(key_.size()) + " bytes; expected at least " +
                    std::to_string(kMinKeyBytes));
  }
  if (!valid_sender(sender_)) {
    throw AuthError("link authentication: sender '" + sender_ +
                    "': expected 1-64 characters from A-Z a-z 0-9 _ . : -");
  }
  if (!(window_s_ > 0) || !std::isfinite(window_s_)) {
    throw AuthError("link authentication: window_s must be a positive number of seconds");
  }
  unsigned char nonce[8];
  if (RAND_bytes(nonce, sizeof nonce) != 1) throw AuthError("link authentication: RAND_bytes failed");
  nonce_ = to_hex(nonce, sizeof nonce);
}

std::string MessageAuthenticator::mac_hex(std::string_view topic, std::string_view sender, std::string_view nonce,
                                          std::uint64_t seq, std::int64_t time_ms, std::string_view payload) const {
  std::string data;
  data.reserve(kMagic.size() + topic.size() + sender.size() + nonce.size() + payload.size() + 48);
  data.append(kMagic).push_back('\n');
  data.append(topic).push_back('\n');
  data.append(sender).push_back('\n');
  data.append(nonce).push_back('\n');
  data.append(std::to_string(seq)).push_back('\n');
  data.append(std::to_string(time_ms)).push_back('\n');
  data.append(payload);
  unsigned char out[EVP_MAX_MD_SIZE];
  unsigned int out_len = 0;
  if (HMAC(EVP_sha256(), key_.data(), static_cast<int>(key_.size()), reinterpret_cast<const unsigned char*>(data.data()),
           data.size(), out, &out_len) == nullptr) {
    throw AuthError("link authentication: HMAC-SHA256 failed");
  }
  return to_hex(out, out_len);
}

std::string MessageAuthenticator::sign(std::string_view topic, std::string_view payload, double now_unix_s) {
  std::uint64_t seq = 0;
  {
    std::lock_guard lock(mutex_);
    seq = next_seq_++;
  }
  const auto time_ms = static_cast<std::int64_t>(std::llround(now_unix_s * 1000.0));
  std::string wire(kMagic);
  wire += ' ' + sender_ + ' ' + nonce_ + ' ' + std::to_string(seq) + ' ' + std::to_string(time_ms) + ' ';
  wire += mac_hex(topic, sender_, nonce_, seq, time_ms, payload);
  wire += '\n';
  wire.append(payload);
  return wire;
}

bool MessageAuthenticator::accept_sequence(const std::string& who, std::uint64_t seq, double now_unix_s) {
  // Forget sender processes silent for 2 windows: any message of theirs would be stale by now.
  if (now_unix_s - last_prune_unix_s_ > window_s_) {
    for (auto it = windows_.begin(); it != windows_.end();) {
      it = now_unix_s - it->second.last_seen_unix_s > 2 * window_s_ ? windows_.erase(it) : std::next(it);
    }
    last_prune_unix_s_ = now_unix_s;
  }
  Window& w = windows_[who];
  const auto bit = [](std::uint64_t s) { return std::make_pair(static_cast<std::size_t>((s % kReplayWindow) / 64), s % 64); };
  if (w.any && seq + kReplayWindow <= w.highest) return false;  // behind the window: cannot tell, refuse
  if (w.any && seq <= w.highest) {
    const auto [word, b] = bit(seq);
    if ((w.bits[word] >> b) & 1u) return false;
    w.bits[word] |= std::uint64_t{1} << b;
  } else {
    // Advance: clear the bits of the sequence numbers skipped (they leave or enter the window unseen).
    const std::uint64_t from = w.any ? w.highest + 1 : seq;
    if (!w.any || seq - from >= kReplayWindow) {
      for (auto& x : w.bits) x = 0;
    } else {
      for (std::uint64_t s = from; s < seq; ++s) {
        const auto [word, b] = bit(s);
        w.bits[word] &= ~(std::uint64_t{1} << b);
      }
    }
    const auto [word, b] = bit(seq);
    w.bits[word] |= std::uint64_t{1} << b;
    w.highest = seq;
    w.any = true;
  }
  w.last_seen_unix_s = now_unix_s;
  return true;
}

MessageAuthenticator::Result MessageAuthenticator::verify(std::string_view topic, std::string_view wire,
                                                          double now_unix_s) {
  Result r;
  const auto count = [&](Verdict v) {
    r.verdict = v;
    std::lock_guard lock(mutex_);
    switch (v) {
      case Verdict::Accepted: ++counts_.accepted; break;
      case Verdict::Unsigned: ++counts_.unsigned_messages; break;
      case Verdict::Malformed: ++counts_.malformed; break;
      case Verdict::BadSignature: ++counts_.bad_signature; break;
      case Verdict::Stale: ++counts_.stale; break;
      case Verdict::Replayed: ++counts_.replayed; break;
    }
    return r;
  };
  if (wire.substr(0, kMagic.size()) != kMagic) return count(Verdict::Unsigned);
  const std::size_t eol = wire.find('\n');
  if (eol == std::string_view::npos || eol > 256) return count(Verdict::Malformed);
  std::string_view header = wire.substr(0, eol);
  std::string_view fields[6];
  std::size_t n = 0;
  while (!header.empty() && n < 6) {
    const std::size_t sp = header.find(' ');
    fields[n++] = header.substr(0, sp);
    header = sp == std::string_view::npos ? std::string_view() : header.substr(sp + 1);
  }
  std::uint64_t seq = 0;
  std::int64_t time_ms = 0;
  if (n != 6 || !header.empty() || fields[0] != kMagic || !valid_sender(fields[1]) || fields[2].size() != 16 ||
      !is_hex(fields[2]) || !parse_int(fields[3], seq) || !parse_int(fields[4], time_ms) || fields[5].size() != 64 ||
      !is_hex(fields[5])) {
    return count(Verdict::Malformed);
  }
  r.sender = std::string(fields[1]);
  const std::string_view payload = wire.substr(eol + 1);
  const std::string expected = mac_hex(topic, fields[1], fields[2], seq, time_ms, payload);
  if (CRYPTO_memcmp(expected.data(), fields[5].data(), expected.size()) != 0) return count(Verdict::BadSignature);
  if (std::fabs(static_cast<double>(time_ms) / 1000.0 - now_unix_s) > window_s_) return count(Verdict::Stale);
  {
    std::lock_guard lock(mutex_);
    const std::string who = r.sender + ' ' + std::string(fields[2]);
    if (!accept_sequence(who, seq, now_unix_s)) {
      ++counts_.replayed;
      r.verdict = Verdict::Replayed;
      return r;
    }
  }
  r.payload = std::string(payload);
  return count(Verdict::Accepted);
}

AuthCounts MessageAuthenticator::counts() const {
  std::lock_guard lock(mutex_);
  return counts_;
}

}  // namespace locus::linkauth
