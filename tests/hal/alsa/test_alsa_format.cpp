// Unit tests of the ALSA format mapping (hal/alsa/alsa_format.hpp) and of the `alsa` source/sink
// parameter validation: every format round trip, exact values at the extremes, S24 sign extension,
// clipping, malformed names and values rejected with messages naming what was expected.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "alsa/alsa_format.hpp"
#include "alsa/alsa_source.hpp"
#include "locus/params.hpp"

namespace locus::hal::alsa {
namespace {

std::vector<unsigned char> le_bytes(std::int64_t v, std::size_t n) {
  std::vector<unsigned char> b(n);
  for (std::size_t i = 0; i < n; ++i) b[i] = static_cast<unsigned char>(static_cast<std::uint64_t>(v) >> (8 * i));
  return b;
}

TEST(AlsaFormat, NamesMapBothWays) {
  EXPECT_EQ(to_alsa(SampleFormat::S16), SND_PCM_FORMAT_S16_LE);
  EXPECT_EQ(to_alsa(SampleFormat::S24), SND_PCM_FORMAT_S24_LE);
  EXPECT_EQ(to_alsa(SampleFormat::S24_3), SND_PCM_FORMAT_S24_3LE);
  EXPECT_EQ(to_alsa(SampleFormat::S32), SND_PCM_FORMAT_S32_LE);
  EXPECT_EQ(to_alsa(SampleFormat::Float), SND_PCM_FORMAT_FLOAT_LE);
  for (SampleFormat f : kAutoFormatOrder) {
    EXPECT_EQ(from_alsa(to_alsa(f)), f);
    const auto one = formats_for_name(format_name(f));
    ASSERT_EQ(one.size(), 1u);
    EXPECT_EQ(one[0], f);
    // bytes_per_sample agrees with libasound's own idea of the physical width
    EXPECT_EQ(bytes_per_sample(f) * 8, static_cast<std::size_t>(snd_pcm_format_physical_width(to_alsa(f))));
  }
  EXPECT_FALSE(from_alsa(SND_PCM_FORMAT_U8).has_value());
  EXPECT_FALSE(from_alsa(SND_PCM_FORMAT_S16_BE).has_value());
  const auto autos = formats_for_name("auto");
  ASSERT_EQ(autos.size(), 5u);
  EXPECT_EQ(autos.front(), SampleFormat::Float);
  EXPECT_EQ(autos.back(), SampleFormat::S16);
  EXPECT_EQ(format_choices().front(), "auto");
  EXPECT_EQ(format_choices().size(), 6u);
}

TEST(AlsaFormat, MalformedNamesAreRejectedListingValidOnes) {
  for (const char* bad : {"", "S16", "s16le", "s8", "float64", "auto ", "24", "s24-3"}) {
    try {
      formats_for_name(bad);
      FAIL() << "accepted '" << bad << "'";
    } catch (const std::invalid_argument& e) {
      const std::string m = e.what();
      EXPECT_NE(m.find("'" + std::string(bad) + "'"), std::string::npos) << m;
      EXPECT_NE(m.find("auto, s16, s24, s24_3, s32, float"), std::string::npos) << m;
    }
  }
}

TEST(AlsaFormat, ExactValuesAtTheExtremes) {
  EXPECT_EQ(sample_to_float(SampleFormat::S16, le_bytes(-32768, 2).data()), -1.0f);
  EXPECT_EQ(sample_to_float(SampleFormat::S16, le_bytes(32767, 2).data()), 32767.0f / 32768.0f);
  EXPECT_EQ(sample_to_float(SampleFormat::S16, le_bytes(0, 2).data()), 0.0f);
  EXPECT_EQ(sample_to_float(SampleFormat::S16, le_bytes(1, 2).data()), 0x1p-15f);
  EXPECT_EQ(sample_to_float(SampleFormat::S16, le_bytes(-1, 2).data()), -0x1p-15f);
  EXPECT_EQ(sample_to_float(SampleFormat::S24_3, le_bytes(-8388608, 3).data()), -1.0f);
  EXPECT_EQ(sample_to_float(SampleFormat::S24_3, le_bytes(8388607, 3).data()), 8388607.0f / 8388608.0f);
  EXPECT_EQ(sample_to_float(SampleFormat::S24, le_bytes(-8388608, 4).data()), -1.0f);
  EXPECT_EQ(sample_to_float(SampleFormat::S24, le_bytes(8388607, 4).data()), 8388607.0f / 8388608.0f);
  EXPECT_EQ(sample_to_float(SampleFormat::S32, le_bytes(std::numeric_limits<std::int32_t>::min(), 4).data()), -1.0f);
  // INT32_MAX rounds to 1.0 in float: clamped to the largest float below 1 so the range stays [-1, 1).
  const float s32max = sample_to_float(SampleFormat::S32, le_bytes(std::numeric_limits<std::int32_t>::max(), 4).data());
  EXPECT_LT(s32max, 1.0f);
  EXPECT_EQ(s32max, std::nextafter(1.0f, 0.0f));
  EXPECT_EQ(sample_to_float(SampleFormat::S32, le_bytes(1 << 8, 4).data()), 0x1p-23f);
}

TEST(AlsaFormat, S24SignExtension) {
  // S24_LE in 32 bits: the high byte is ignored (may be garbage), bit 23 is the sign.
  std::vector<unsigned char> b{0xff, 0xff, 0xff, 0x00};  // -1 with a zero high byte
  EXPECT_EQ(sample_to_float(SampleFormat::S24, b.data()), -0x1p-23f);
  b = {0xff, 0xff, 0x7f, 0xff};  // +8388607 with a 0xff high byte
  EXPECT_EQ(sample_to_float(SampleFormat::S24, b.data()), 8388607.0f / 8388608.0f);
  b = {0x00, 0x00, 0x80, 0x00};  // -8388608
  EXPECT_EQ(sample_to_float(SampleFormat::S24, b.data()), -1.0f);
  b = {0x00, 0x00, 0x80};
  EXPECT_EQ(sample_to_float(SampleFormat::S24_3, b.data()), -1.0f);
  b = {0x01, 0x00, 0x00};
  EXPECT_EQ(sample_to_float(SampleFormat::S24_3, b.data()), 0x1p-23f);
  // float -> S24 writes the sign into the high byte too
  unsigned char out[4];
  sample_from_float(SampleFormat::S24, -0x1p-23f, out);
  EXPECT_EQ(out[0], 0xff);
  EXPECT_EQ(out[1], 0xff);
  EXPECT_EQ(out[2], 0xff);
  EXPECT_EQ(out[3], 0xff);
}

TEST(AlsaFormat, EveryFormatRoundTripsRawFloatRaw) {
  std::mt19937 rng(7);
  for (SampleFormat f : kAutoFormatOrder) {
    const std::size_t bps = bytes_per_sample(f);
    const std::size_t n = 4096;
    std::vector<unsigned char> raw(n * bps);
    for (std::size_t i = 0; i < n; ++i) {
      std::int64_t v = 0;
      switch (f) {
        case SampleFormat::S16: v = static_cast<std::int16_t>(rng()); break;
        case SampleFormat::S24:
        case SampleFormat::S24_3: v = static_cast<std::int32_t>(rng() << 8) >> 8; break;
        // Only 24 significant bits survive float: use values exactly representable (multiples of 2^8).
        case SampleFormat::S32: v = static_cast<std::int32_t>(rng() & 0xffffff00u); break;
        case SampleFormat::Float: {
          const float x = std::uniform_real_distribution<float>(-1.0f, 1.0f)(rng);
          std::uint32_t u;
          std::memcpy(&u, &x, 4);
          v = u;
          break;
        }
      }
      if (i == 0) v = f == SampleFormat::S16 ? -32768 : f == SampleFormat::Float ? 0xbf800000 : (f == SampleFormat::S32 ? INT32_MIN : -8388608);
      const auto b = le_bytes(v, bps);
      std::memcpy(raw.data() + i * bps, b.data(), bps);
    }
    if (f == SampleFormat::S24)  // canonical S24 in 32 bits: sign-extended high byte
      for (std::size_t i = 0; i < n; ++i) raw[i * 4 + 3] = (raw[i * 4 + 2] & 0x80) ? 0xff : 0x00;
    std::vector<float> x(n);
    raw_to_float(f, raw.data(), x.data(), n);
    for (float v : x) {
      ASSERT_GE(v, -1.0f) << format_name(f);
      ASSERT_LT(v, 1.0f) << format_name(f);
    }
    std::vector<unsigned char> back(n * bps, 0xaa);
    float_to_raw(f, x.data(), back.data(), n);
    EXPECT_EQ(back, raw) << "format " << format_name(f);
  }
}

TEST(AlsaFormat, FloatToRawRoundsAndClips) {
  unsigned char b[4];
  auto s16 = [&](float x) {
    sample_from_float(SampleFormat::S16, x, b);
    return static_cast<std::int16_t>(b[0] | (b[1] << 8));
  };
  EXPECT_EQ(s16(-1.0f), -32768);
  EXPECT_EQ(s16(-2.0f), -32768);
  EXPECT_EQ(s16(1.0f), 32767);
  EXPECT_EQ(s16(5.0f), 32767);
  EXPECT_EQ(s16(std::numeric_limits<float>::infinity()), 32767);
  EXPECT_EQ(s16(-std::numeric_limits<float>::infinity()), -32768);
  EXPECT_EQ(s16(std::numeric_limits<float>::quiet_NaN()), 0);
  EXPECT_EQ(s16(0.5f), 16384);
  EXPECT_EQ(s16(1.4f / 32768.0f), 1);   // nearest
  EXPECT_EQ(s16(1.6f / 32768.0f), 2);
  EXPECT_EQ(s16(-1.6f / 32768.0f), -2);
  auto s32 = [&](float x) {
    sample_from_float(SampleFormat::S32, x, b);
    std::uint32_t u = b[0] | (b[1] << 8) | (b[2] << 16) | (std::uint32_t{b[3]} << 24);
    return static_cast<std::int32_t>(u);
  };
  EXPECT_EQ(s32(1.0f), INT32_MAX);
  EXPECT_EQ(s32(-1.0f), INT32_MIN);
  EXPECT_EQ(s32(-3.0f), INT32_MIN);
  EXPECT_EQ(s32(0.25f), 1 << 29);
  auto s24_3 = [&](float x) {
    sample_from_float(SampleFormat::S24_3, x, b);
    return static_cast<std::int32_t>((b[0] | (b[1] << 8) | (b[2] << 16)) << 8) >> 8;
  };
  EXPECT_EQ(s24_3(1.0f), 8388607);
  EXPECT_EQ(s24_3(-1.0f), -8388608);
  EXPECT_EQ(s24_3(-0.5f), -4194304);
  auto flt = [&](float x) {
    sample_from_float(SampleFormat::Float, x, b);
    float y;
    std::uint32_t u = b[0] | (b[1] << 8) | (b[2] << 16) | (std::uint32_t{b[3]} << 24);
    std::memcpy(&y, &u, 4);
    return y;
  };
  EXPECT_EQ(flt(0.123f), 0.123f);
  EXPECT_EQ(flt(1.5f), 1.0f);
  EXPECT_EQ(flt(-7.0f), -1.0f);
  EXPECT_EQ(flt(std::numeric_limits<float>::quiet_NaN()), 0.0f);
}

TEST(AlsaFormat, FloatInputNonFiniteIsSanitised) {
  const float in[3] = {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(),
                       -std::numeric_limits<float>::infinity()};
  float out[3];
  raw_to_float(SampleFormat::Float, in, out, 3);  // host is little-endian here (checked below)
  const std::uint16_t probe = 1;
  if (*reinterpret_cast<const unsigned char*>(&probe) != 1) GTEST_SKIP() << "big-endian host";
  EXPECT_EQ(out[0], 0.0f);
  EXPECT_EQ(out[1], 1.0f);
  EXPECT_EQ(out[2], -1.0f);
}

// ---------------------------------------------------------------- parameters

Params valid_params() { return Params::defaults(alsa_source_schema()); }

void expect_rejected(Params p, const std::string& needle) {
  try {
    AlsaStreamConfig::from_params(p, SND_PCM_STREAM_CAPTURE);
    FAIL() << "accepted, expected an error containing '" << needle << "'";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).rfind("alsa source: ", 0), 0u) << e.what();
  }
}

TEST(AlsaParams, DefaultsAreValid) {
  const AlsaStreamConfig c = AlsaStreamConfig::from_params(valid_params(), SND_PCM_STREAM_CAPTURE);
  EXPECT_EQ(c.request.pcm, "default");
  EXPECT_EQ(c.request.channels, 1u);
  EXPECT_EQ(c.request.format, "auto");
  EXPECT_EQ(c.request.rate_hz, 44100u);
  EXPECT_EQ(c.request.period_frames, 256u);
  EXPECT_EQ(c.request.periods, 4u);
  EXPECT_EQ(c.request.config_file, "");
  EXPECT_EQ(c.max_frames, 0u);
  EXPECT_EQ(c.retry_max, 10u);
  EXPECT_GT(c.retry_backoff_s, 0.0);
  // The schema lists the format names as enum choices.
  bool found = false;
  for (const ParamSpec& s : alsa_source_schema())
    if (s.key == "format") {
      found = true;
      EXPECT_EQ(s.choices, format_choices());
    }
  EXPECT_TRUE(found);
  EXPECT_EQ(alsa_sink_schema().size(), alsa_source_schema().size());
}

TEST(AlsaParams, MalformedValuesAreRejected) {
  Params p = valid_params();
  p.set("format", std::string("s8"));
  expect_rejected(p, "format 's8' is unknown (expected one of: auto, s16, s24, s24_3, s32, float)");
  p = valid_params();
  p.set("pcm", std::string(""));
  expect_rejected(p, "pcm is empty");
  p = valid_params();
  p.set("sample_rate_hz", 44100.5);
  expect_rejected(p, "sample_rate_hz must be a whole number of Hz");
  p = valid_params();
  p.set("channels", std::int64_t{0});
  expect_rejected(p, "channels must be 1..32 (got 0)");
  p = valid_params();
  p.set("channels", std::int64_t{33});
  expect_rejected(p, "channels must be 1..32 (got 33)");
  p = valid_params();
  p.set("periods", std::int64_t{1});
  expect_rejected(p, "periods must be 2..64");
  p = valid_params();
  p.set("max_frames", std::int64_t{-1});
  expect_rejected(p, "max_frames must be >= 0");
  p = valid_params();
  p.set("retry_backoff_s", 2.0);
  p.set("retry_backoff_max_s", 1.0);
  expect_rejected(p, "retry_backoff_max_s (1) must be >= retry_backoff_s (2)");
  p = valid_params();
  p.set("stall_timeout_s", -1.0);
  expect_rejected(p, "stall_timeout_s must be >= 0");
  p = valid_params();
  p.set("channels", std::string("two"));  // mistyped (never from the validator, but must not crash)
  expect_rejected(p, "missing or mistyped parameter");
}

}  // namespace
}  // namespace locus::hal::alsa
