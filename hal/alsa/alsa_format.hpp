// ALSA sample formats: the config names (`format:` of the `alsa` source and sink), their
// snd_pcm_format_t, the negotiation order of `auto`, and the conversions between interleaved raw
// frames and interleaved float frames.
//
// Why here and not in libasound's plug plugin: the capture thread must convert without allocating,
// and the exact float value of every raw sample is part of the contract (tests compare bit-exact).
// The mapping is:
//   s16   SND_PCM_FORMAT_S16_LE     2 bytes   x = v / 2^15            (-32768 -> -1.0, exact)
//   s24   SND_PCM_FORMAT_S24_LE     4 bytes   low 24 bits, sign-extended from bit 23; x = v / 2^23 (exact)
//   s24_3 SND_PCM_FORMAT_S24_3LE    3 bytes   packed 24 bits, sign-extended;            x = v / 2^23 (exact)
//   s32   SND_PCM_FORMAT_S32_LE     4 bytes   x = v / 2^31 rounded to float (24-bit mantissa), and
//                                             clamped to the largest float below 1.0 so x is in [-1, 1)
//   float SND_PCM_FORMAT_FLOAT_LE   4 bytes   passed through bit-exact; NaN -> 0, +-inf -> +-1
// Raw bytes are always little-endian and are assembled byte by byte, so the code is host-endian safe.
// float -> raw rounds to nearest and clips to the format's range (NaN -> 0); float output is clipped
// to [-1, 1].
//
// `auto` tries FLOAT, S32, S24, S24_3, S16 in that order: the first format the PCM accepts without
// losing precision wins. On `plughw:`/`plug` PCMs (which accept everything) this gives float, i.e.
// the plugin converts the card's native integers losslessly (a 24-bit sample fits a float mantissa);
// on `hw:` PCMs it picks the card's widest native format.
#pragma once

#include <alsa/asoundlib.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace locus::hal::alsa {

enum class SampleFormat : std::uint8_t { S16, S24, S24_3, S32, Float };

/// Every concrete format, in the order of `auto` negotiation.
inline constexpr std::array<SampleFormat, 5> kAutoFormatOrder{SampleFormat::Float, SampleFormat::S32, SampleFormat::S24,
                                                               SampleFormat::S24_3, SampleFormat::S16};

/// The names the config accepts, `auto` first (for schemas and error messages).
const std::vector<std::string>& format_choices();

/// Config name of a format ("s16", "s24", "s24_3", "s32", "float").
std::string_view format_name(SampleFormat f) noexcept;
/// The ALSA format (little-endian variants).
snd_pcm_format_t to_alsa(SampleFormat f) noexcept;
/// The inverse of to_alsa; nullopt for any other ALSA format.
std::optional<SampleFormat> from_alsa(snd_pcm_format_t f) noexcept;
/// Bytes one sample occupies in an interleaved buffer (2, 4, 3, 4, 4).
std::size_t bytes_per_sample(SampleFormat f) noexcept;

/// The formats to try for a config name: one for a concrete name, kAutoFormatOrder for "auto".
/// Throws std::invalid_argument "format '<name>' is unknown (expected one of: auto, s16, ...)".
std::vector<SampleFormat> formats_for_name(std::string_view name);

/// [RT] `samples` raw samples (frames * channels, interleaved) to floats in [-1, 1). No allocation.
void raw_to_float(SampleFormat f, const void* raw, float* out, std::size_t samples) noexcept;
/// [RT] `samples` floats to raw samples, rounded to nearest and clipped to the format's range.
void float_to_raw(SampleFormat f, const float* in, void* raw, std::size_t samples) noexcept;

/// [any] One sample each way (the loops above use the same code; exposed for tests).
float sample_to_float(SampleFormat f, const unsigned char* raw) noexcept;
void sample_from_float(SampleFormat f, float x, unsigned char* raw) noexcept;

}  // namespace locus::hal::alsa
