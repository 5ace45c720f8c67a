// See alsa_format.hpp for the mapping and why the conversions live here.
#include "alsa/alsa_format.hpp"

#include <cmath>
#include <cstring>
#include <stdexcept>

namespace locus::hal::alsa {

namespace {

constexpr float kBelowOne = 0x1.fffffep-1f;  // the largest float below 1.0

inline std::int32_t load_s16(const unsigned char* p) noexcept {
  return static_cast<std::int16_t>(static_cast<std::uint16_t>(p[0] | (p[1] << 8)));
}
inline std::int32_t load_s24_low(const unsigned char* p) noexcept {  // 24 bits in the 3 low bytes
  const std::uint32_t u = std::uint32_t{p[0]} | (std::uint32_t{p[1]} << 8) | (std::uint32_t{p[2]} << 16);
  return static_cast<std::int32_t>(u << 8) >> 8;  // sign-extend from bit 23
}
inline std::int32_t load_s32(const unsigned char* p) noexcept {
  const std::uint32_t u = std::uint32_t{p[0]} | (std::uint32_t{p[1]} << 8) | (std::uint32_t{p[2]} << 16) |
                          (std::uint32_t{p[3]} << 24);
  return static_cast<std::int32_t>(u);
}
inline void store_le(unsigned char* p, std::uint32_t u, std::size_t bytes) noexcept {
  for (std::size_t i = 0; i < bytes; ++i) p[i] = static_cast<unsigned char>(u >> (8 * i));
}

/// Rounds x * scale to nearest and clips to [lo, hi]; NaN -> 0.
inline std::int32_t quantize(float x, double scale, double lo, double hi) noexcept {
  if (std::isnan(x)) return 0;
  double v = std::nearbyint(static_cast<double>(x) * scale);
  if (v < lo) v = lo;
  if (v > hi) v = hi;
  return static_cast<std::int32_t>(v);
}

inline float decode(SampleFormat f, const unsigned char* p) noexcept {
  switch (f) {
    case SampleFormat::S16:
      return static_cast<float>(load_s16(p)) * 0x1p-15f;
    case SampleFormat::S24:
    case SampleFormat::S24_3:
      return static_cast<float>(load_s24_low(p)) * 0x1p-23f;
    case SampleFormat::S32: {
      const float x = static_cast<float>(static_cast<double>(load_s32(p)) * 0x1p-31);
      return x < 1.0f ? x : kBelowOne;
    }
    case SampleFormat::Float: {
      float x;
      const std::uint32_t u = static_cast<std::uint32_t>(load_s32(p));
      std::memcpy(&x, &u, sizeof x);
      if (!std::isfinite(x)) return std::isnan(x) ? 0.0f : (x > 0 ? 1.0f : -1.0f);
      return x;
    }
  }
  return 0.0f;
}

inline void encode(SampleFormat f, float x, unsigned char* p) noexcept {
  switch (f) {
    case SampleFormat::S16:
      store_le(p, static_cast<std::uint32_t>(quantize(x, 0x1p15, -32768.0, 32767.0)), 2);
      return;
    case SampleFormat::S24:  // sign-extended into the high byte
      store_le(p, static_cast<std::uint32_t>(quantize(x, 0x1p23, -8388608.0, 8388607.0)), 4);
      return;
    case SampleFormat::S24_3:
      store_le(p, static_cast<std::uint32_t>(quantize(x, 0x1p23, -8388608.0, 8388607.0)), 3);
      return;
    case SampleFormat::S32:
      store_le(p, static_cast<std::uint32_t>(quantize(x, 0x1p31, -2147483648.0, 2147483647.0)), 4);
      return;
    case SampleFormat::Float: {
      float y = std::isnan(x) ? 0.0f : (x < -1.0f ? -1.0f : (x > 1.0f ? 1.0f : x));
      std::uint32_t u;
      std::memcpy(&u, &y, sizeof u);
      store_le(p, u, 4);
      return;
    }
  }
}

template <SampleFormat F>
void to_float_loop(const unsigned char* raw, float* out, std::size_t samples) noexcept {
  constexpr std::size_t step = F == SampleFormat::S16 ? 2 : F == SampleFormat::S24_3 ? 3 : 4;
  for (std::size_t i = 0; i < samples; ++i) out[i] = decode(F, raw + i * step);
}

template <SampleFormat F>
void from_float_loop(const float* in, unsigned char* raw, std::size_t samples) noexcept {
  constexpr std::size_t step = F == SampleFormat::S16 ? 2 : F == SampleFormat::S24_3 ? 3 : 4;
  for (std::size_t i = 0; i < samples; ++i) encode(F, in[i], raw + i * step);
}

}  // namespace

const std::vector<std::string>& format_choices() {
  static const std::vector<std::string> names{"auto", "s16", "s24", "s24_3", "s32", "float"};
  return names;
}

std::string_view format_name(SampleFormat f) noexcept {
  switch (f) {
    case SampleFormat::S16: return "s16";
    case SampleFormat::S24: return "s24";
    case SampleFormat::S24_3: return "s24_3";
    case SampleFormat::S32: return "s32";
    case SampleFormat::Float: return "float";
  }
  return "?";
}

snd_pcm_format_t to_alsa(SampleFormat f) noexcept {
  switch (f) {
    case SampleFormat::S16: return SND_PCM_FORMAT_S16_LE;
    case SampleFormat::S24: return SND_PCM_FORMAT_S24_LE;
    case SampleFormat::S24_3: return SND_PCM_FORMAT_S24_3LE;
    case SampleFormat::S32: return SND_PCM_FORMAT_S32_LE;
    case SampleFormat::Float: return SND_PCM_FORMAT_FLOAT_LE;
  }
  return SND_PCM_FORMAT_UNKNOWN;
}

std::optional<SampleFormat> from_alsa(snd_pcm_format_t f) noexcept {
  for (SampleFormat s : kAutoFormatOrder)
    if (to_alsa(s) == f) return s;
  return std::nullopt;
}

std::size_t bytes_per_sample(SampleFormat f) noexcept {
  switch (f) {
    case SampleFormat::S16: return 2;
    case SampleFormat::S24_3: return 3;
    case SampleFormat::S24:
    case SampleFormat::S32:
    case SampleFormat::Float: return 4;
  }
  return 0;
}

std::vector<SampleFormat> formats_for_name(std::string_view name) {
  if (name == "auto") return {kAutoFormatOrder.begin(), kAutoFormatOrder.end()};
  for (SampleFormat s : kAutoFormatOrder)
    if (format_name(s) == name) return {s};
  std::string valid;
  for (const std::string& c : format_choices()) valid += (valid.empty() ? "" : ", ") + c;
  throw std::invalid_argument("format '" + std::string(name) + "' is unknown (expected one of: " + valid + ")");
}

void raw_to_float(SampleFormat f, const void* raw, float* out, std::size_t samples) noexcept {
  const auto* p = static_cast<const unsigned char*>(raw);
  switch (f) {
    case SampleFormat::S16: to_float_loop<SampleFormat::S16>(p, out, samples); return;
    case SampleFormat::S24: to_float_loop<SampleFormat::S24>(p, out, samples); return;
    case SampleFormat::S24_3: to_float_loop<SampleFormat::S24_3>(p, out, samples); return;
    case SampleFormat::S32: to_float_loop<SampleFormat::S32>(p, out, samples); return;
    case SampleFormat::Float: to_float_loop<SampleFormat::Float>(p, out, samples); return;
  }
}

void float_to_raw(SampleFormat f, const float* in, void* raw, std::size_t samples) noexcept {
  auto* p = static_cast<unsigned char*>(raw);
  switch (f) {
    case SampleFormat::S16: from_float_loop<SampleFormat::S16>(in, p, samples); return;
    case SampleFormat::S24: from_float_loop<SampleFormat::S24>(in, p, samples); return;
    case SampleFormat::S24_3: from_float_loop<SampleFormat::S24_3>(in, p, samples); return;
    case SampleFormat::S32: from_float_loop<SampleFormat::S32>(in, p, samples); return;
    case SampleFormat::Float: from_float_loop<SampleFormat::Float>(in, p, samples); return;
  }
}

float sample_to_float(SampleFormat f, const unsigned char* raw) noexcept { return decode(f, raw); }
void sample_from_float(SampleFormat f, float x, unsigned char* raw) noexcept { encode(f, x, raw); }

}  // namespace locus::hal::alsa
