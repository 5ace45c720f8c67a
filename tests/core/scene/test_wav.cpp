// audio.wav: round trips in the four sample formats (exact quantisation), hand-built headers
// (extensible, extra chunks, streaming size), truncation, seeking and bounded-memory block reads.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "locus/scene/streams.hpp"
#include "scene_test_util.hpp"

using namespace locus::scene;
using namespace locus::scene::test;

namespace {

std::vector<float> read_all(WavReader& r, std::size_t block = 1000) {
  std::vector<float> out, buf(block * static_cast<std::size_t>(r.info().channels));
  while (std::size_t n = r.read(buf.data(), block)) out.insert(out.end(), buf.begin(), buf.begin() + n * r.info().channels);
  return out;
}

}  // namespace

TEST(SceneWav, FloatRoundTripIsBitExact) {
  TempDir tmp;
  const std::string p = tmp / "f.wav";
  std::mt19937 rng(1);
  std::normal_distribution<float> nd(0.0f, 0.3f);
  std::vector<float> x(3 * 10007);
  for (float& v : x) v = nd(rng);
  x[5] = 1.7f;  // float files are not clipped
  {
    WavWriter w(p, 3, 44100, WavSampleFormat::Float32);
    w.write(x.data(), 5000);
    w.write(x.data() + 3 * 5000, 5007);
    EXPECT_EQ(w.frames_written(), 10007u);
    w.close();
  }
  WavReader r(p);
  EXPECT_EQ(r.info().channels, 3);
  EXPECT_EQ(r.info().sample_rate_hz, 44100.0);
  EXPECT_EQ(r.info().frames, 10007u);
  EXPECT_EQ(r.info().sample_format, WavSampleFormat::Float32);
  EXPECT_FALSE(r.truncated());
  EXPECT_EQ(r.truncation_message(), "");
  const auto y = read_all(r, 777);
  ASSERT_EQ(y.size(), x.size());
  for (std::size_t i = 0; i < x.size(); ++i) ASSERT_EQ(y[i], x[i]) << i;
}

class SceneWavInt : public ::testing::TestWithParam<std::pair<WavSampleFormat, int>> {};

TEST_P(SceneWavInt, QuantisationIsExactAndClamped) {
  const auto [fmt, bits] = GetParam();
  TempDir tmp;
  const std::string p = tmp / "i.wav";
  const double scale = std::ldexp(1.0, bits - 1);
  // values on the grid, half-way points, out-of-range values and NaN
  std::vector<float> x = {0.0f, 0.5f, -0.5f, -1.0f, 1.0f, 2.0f, -3.0f, std::nanf(""),
                          static_cast<float>(1.0 / scale), static_cast<float>(-1.0 / scale),
                          static_cast<float>(1234.0 / scale), static_cast<float>(0.25 / scale)};
  std::mt19937 rng(2);
  std::uniform_real_distribution<float> ud(-1.0f, 1.0f);
  for (int i = 0; i < 1000; ++i) x.push_back(ud(rng));
  if (x.size() % 2) x.push_back(0.125f);
  {
    WavWriter w(p, 2, 48000, fmt);
    w.write(x.data(), x.size() / 2);
    w.close();
  }
  WavReader r(p);
  EXPECT_EQ(r.info().sample_format, fmt);
  EXPECT_EQ(r.info().frames, x.size() / 2);
  const auto y = read_all(r);
  ASSERT_EQ(y.size(), x.size());
  for (std::size_t i = 0; i < x.size(); ++i) {
    double q = std::isnan(x[i]) ? 0.0 : std::nearbyint(std::clamp(double(x[i]) * scale, -scale, scale - 1.0));
    const float expect = static_cast<float>(q / scale);
    ASSERT_EQ(y[i], expect) << "sample " << i << " x=" << x[i];
  }
  EXPECT_EQ(y[2 * 0 + 4], static_cast<float>((scale - 1.0) / scale));  // 1.0 clamps to max
  EXPECT_EQ(y[6], -1.0f);                                               // -3 clamps to min
  // the file holds the expected integers (independent of the reader): sample 1 = 0.5 -> 2^(bits-2)
  const std::string bytes = read_file(p);
  const WavInfo info = read_wav_info(p);
  const int bps = bits / 8;
  long long v = 0;
  for (int b = bps - 1; b >= 0; --b) v = (v << 8) | static_cast<unsigned char>(bytes[info.data_offset + bps + b]);
  EXPECT_EQ(v, 1LL << (bits - 2));
}

INSTANTIATE_TEST_SUITE_P(Formats, SceneWavInt,
                         ::testing::Values(std::make_pair(WavSampleFormat::Int16, 16),
                                           std::make_pair(WavSampleFormat::Int24, 24),
                                           std::make_pair(WavSampleFormat::Int32, 32)));

TEST(SceneWav, HandBuiltPcmAndExtensibleFilesRead) {
  TempDir tmp;
  // int16 stereo, a LIST chunk of odd size (padded) between fmt and data
  RawWav w;
  w.channels = 2;
  w.rate = 44100;
  for (int v : {0, 1, -1, 16384, -32768, 32767}) put16(w.data, static_cast<unsigned>(v) & 0xFFFF);
  w.extra_chunks = std::string("LIST") + std::string("\x03\x00\x00\x00", 4) + "abc" + std::string(1, '\0');
  write_file(tmp / "a.wav", build_wav(w));
  WavReader r(tmp / "a.wav");
  EXPECT_FALSE(r.info().extensible);
  EXPECT_EQ(r.info().frames, 3u);
  std::vector<float> y = read_all(r);
  std::vector<float> expect = {0.0f, 1.0f / 32768, -1.0f / 32768, 0.5f, -1.0f, 32767.0f / 32768};
  EXPECT_EQ(y, expect);

  // WAVE_FORMAT_EXTENSIBLE float32, 1 channel
  RawWav e;
  e.tag = 0xFFFE;
  e.sub_tag = 3;
  e.bits = 32;
  for (float f : {0.25f, -0.75f}) {
    std::uint32_t u;
    std::memcpy(&u, &f, 4);
    put32(e.data, u);
  }
  write_file(tmp / "e.wav", build_wav(e));
  WavReader re(tmp / "e.wav");
  EXPECT_TRUE(re.info().extensible);
  EXPECT_EQ(re.info().sample_format, WavSampleFormat::Float32);
  EXPECT_EQ(read_all(re), (std::vector<float>{0.25f, -0.75f}));

  // extensible int24
  RawWav e24;
  e24.tag = 0xFFFE;
  e24.sub_tag = 1;
  e24.bits = 24;
  e24.data = std::string("\x00\x00\x40\xFF\xFF\xFF", 6);  // 0x400000 = 0.5, -1
  write_file(tmp / "e24.wav", build_wav(e24));
  WavReader r24(tmp / "e24.wav");
  EXPECT_EQ(read_all(r24), (std::vector<float>{0.5f, -1.0f / 8388608}));
}

TEST(SceneWav, TruncatedDataDeliversWholeFramesAndSaysSo) {
  TempDir tmp;
  RawWav w;
  w.channels = 2;
  for (int i = 0; i < 10; ++i) put16(w.data, static_cast<unsigned>(i * 100));
  w.data.pop_back();          // 19 bytes: 4 whole frames + 3 bytes
  w.declared_data = 400;      // header says 100 frames
  const std::string p = tmp / "t.wav";
  write_file(p, build_wav(w));
  WavReader r(p);
  EXPECT_TRUE(r.truncated());
  EXPECT_EQ(r.info().frames, 4u);
  EXPECT_EQ(r.info().declared_data_bytes, 400u);
  EXPECT_EQ(r.truncation_message(),
            p + ": byte 40: truncated data chunk: header declares 400 bytes, the file holds 16 (4 whole frames kept)");
  const auto y = read_all(r);
  ASSERT_EQ(y.size(), 8u);
  for (int i = 0; i < 8; ++i) EXPECT_EQ(y[i], static_cast<float>(i * 100) / 32768.0f);
}

TEST(SceneWav, StreamingSizeRunsToEndOfFile) {
  TempDir tmp;
  RawWav w;
  for (int i = 0; i < 5; ++i) put16(w.data, static_cast<unsigned>(i));
  w.declared_data = 0xFFFFFFFFLL;
  write_file(tmp / "s.wav", build_wav(w));
  const WavInfo info = read_wav_info(tmp / "s.wav");
  EXPECT_FALSE(info.truncated);
  EXPECT_EQ(info.frames, 5u);
}

TEST(SceneWav, SeekAndPosition) {
  TempDir tmp;
  const std::string p = tmp / "seek.wav";
  std::vector<float> x(2 * 1000);
  for (std::size_t i = 0; i < x.size(); ++i) x[i] = static_cast<float>(i) / 4096.0f;
  {
    WavWriter w(p, 2, 16000, WavSampleFormat::Int24);
    w.write(x.data(), 1000);
  }  // destructor closes
  WavReader r(p);
  r.seek(600);
  EXPECT_EQ(r.position(), 600u);
  float buf[4];
  ASSERT_EQ(r.read(buf, 2), 2u);
  EXPECT_EQ(buf[0], x[1200]);
  EXPECT_EQ(buf[3], x[1203]);
  EXPECT_EQ(r.position(), 602u);
  r.seek(5000);  // clamped to the end
  EXPECT_EQ(r.position(), 1000u);
  EXPECT_EQ(r.read(buf, 2), 0u);
  r.seek(0);
  ASSERT_EQ(r.read(buf, 1), 1u);
  EXPECT_EQ(buf[1], x[1]);
  // move keeps the stream
  WavReader moved = std::move(r);
  ASSERT_EQ(moved.read(buf, 1), 1u);
  EXPECT_EQ(buf[0], x[2]);
}

TEST(SceneWav, WriterRejectsBadArguments) {
  TempDir tmp;
  EXPECT_THROW(WavWriter(tmp / "x.wav", 0, 48000), std::invalid_argument);
  EXPECT_THROW(WavWriter(tmp / "x.wav", 1, 44100.5), std::invalid_argument);
  EXPECT_THROW(WavWriter(tmp / "x.wav", 1, -1.0), std::invalid_argument);
  EXPECT_THROW(WavWriter(tmp / "no/such/dir/x.wav", 1, 48000), std::runtime_error);
}
