// The ALSA backend through real libasound, without a sound card: PCMs are user-space plugins defined
// in a private config file (config_file), as docs/hal-alsa.md and real-components.md describe.
//
//  - capture: a known LFM chirp written as raw samples is read through `type file` (infile) over
//    `null`; every frame must come out bit-exact at its frame number, in every format, 1 and 2 ch;
//  - playback: a clip scheduled at frame F on a PlaybackScheduler is played through `type file` over
//    `null` into a file; it must be there at frame F, bit-exact, with silence around it;
//  - bad input: unknown PCM, unreadable or malformed config_file, a PCM that cannot do the rate
//    (a `jack` PCM on a dummy jackd at 48 kHz) fail at open() with a message naming the cause;
//  - device loss: a PCM whose data stops (stall) and whose file is gone is retried retry_max times
//    and then ends with error() naming the PCM and the errno text, without a hang; a PCM that comes
//    back resumes with the gap reported as lost frames at the right place;
//  - real-time pacing: capture through the `jack` PCM on a dummy jackd; xruns are counted and
//    reported (not asserted zero), and the stream clock accounts for every frame.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <jack/jack.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <mutex>
#include <numbers>
#include <string>
#include <thread>
#include <vector>

#include "alsa/alsa_devices.hpp"
#include "alsa/alsa_format.hpp"
#include "alsa/alsa_sink.hpp"
#include "alsa/alsa_source.hpp"
#include "locus/audio_ring.hpp"
#include "locus/config.hpp"
#include "locus/pipeline.hpp"
#include "locus/registry.hpp"
#include "locus/playback.hpp"
#include "support/test_host.hpp"

extern char** environ;

namespace locus::hal::alsa {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr std::uint32_t kRate = 44100;

struct TempDir {
  fs::path path;
  TempDir() {
    std::string tmpl = (fs::temp_directory_path() / "locus_alsa_XXXXXX").string();
    if (!::mkdtemp(tmpl.data())) throw std::runtime_error("mkdtemp failed");
    path = tmpl;
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  std::string file(const std::string& name) const { return (path / name).string(); }
};

void write_bytes(const std::string& path, const std::vector<unsigned char>& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  ASSERT_TRUE(out.good()) << path;
}

std::vector<unsigned char> read_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::trunc);
  out << text;
}

/// A linear chirp f0 -> f1 over `frames` frames at amplitude `amp` (channel c is delayed by 7*c frames
/// so channels differ), as doubles in (-1, 1).
std::vector<double> chirp(std::size_t frames, std::uint32_t channels, double amp = 0.8) {
  const double f0 = 500.0, f1 = 9000.0, d = static_cast<double>(frames) / kRate;
  std::vector<double> x(frames * channels);
  for (std::size_t i = 0; i < frames; ++i)
    for (std::uint32_t c = 0; c < channels; ++c) {
      const double t = static_cast<double>(i + 7 * c) / kRate;
      x[i * channels + c] = amp * std::sin(2.0 * std::numbers::pi * (f0 * t + (f1 - f0) * t * t / (2.0 * d)));
    }
  return x;
}

/// The chirp encoded as raw little-endian samples of `f`, and the float each sample must become
/// (computed here from the integer, independently of the converter under test).
struct Encoded {
  std::vector<unsigned char> raw;
  std::vector<float> expected;
};

Encoded encode(SampleFormat f, const std::vector<double>& x) {
  Encoded e;
  const std::size_t bps = bytes_per_sample(f);
  e.raw.resize(x.size() * bps);
  e.expected.resize(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) {
    std::int64_t q = 0;
    unsigned char* p = e.raw.data() + i * bps;
    switch (f) {
      case SampleFormat::S16:
        q = std::llround(x[i] * 32767.0);
        e.expected[i] = static_cast<float>(q) / 32768.0f;
        break;
      case SampleFormat::S24:
      case SampleFormat::S24_3:
        q = std::llround(x[i] * 8388607.0);
        e.expected[i] = static_cast<float>(q) / 8388608.0f;
        break;
      case SampleFormat::S32:
        q = std::llround(x[i] * 8388607.0) * 256;  // 24 significant bits: exact in float
        e.expected[i] = static_cast<float>(static_cast<double>(q) / 2147483648.0);
        break;
      case SampleFormat::Float: {
        const float v = static_cast<float>(x[i]);
        std::uint32_t u;
        std::memcpy(&u, &v, 4);
        q = u;
        e.expected[i] = v;
        break;
      }
    }
    for (std::size_t b = 0; b < bps; ++b) p[b] = static_cast<unsigned char>(static_cast<std::uint64_t>(q) >> (8 * b));
  }
  return e;
}

std::string file_pcm(const std::string& name, const std::string& infile) {
  return "pcm." + name + " {\n  type file\n  slave.pcm \"null\"\n  file \"/dev/null\"\n  infile \"" + infile +
         "\"\n  format \"raw\"\n}\n";
}

AlsaStreamConfig capture_config(const std::string& pcm, const std::string& config_file, const std::string& format,
                                std::uint32_t channels, std::uint64_t max_frames) {
  AlsaStreamConfig c;
  c.request.pcm = pcm;
  c.request.config_file = config_file;
  c.request.format = format;
  c.request.channels = channels;
  c.request.rate_hz = kRate;
  c.max_frames = max_frames;
  c.retry_max = 0;
  c.stall_timeout_s = 1.0;
  return c;
}

/// What came out of a ring: the samples in stream order and the gaps (first frame after, frames lost).
struct Drained {
  std::vector<float> samples;
  std::vector<std::uint64_t> first_frames;  // first_frame of each read that followed a gap
  std::vector<std::uint64_t> gaps;          // lost_before of those reads
  std::uint64_t next_frame = 0;
};

/// Reads `ring` until `done()` and the ring is empty, or `timeout_s`.
template <typename Done>
Drained drain(AudioRing& ring, Done done, double timeout_s = 30.0) {
  Drained d;
  std::vector<float> buf(4096 * ring.channels());
  const auto deadline = Clock::now() + std::chrono::duration<double>(timeout_s);
  for (;;) {
    const bool was_done = done();  // checked before reading: nothing is written after done()
    std::uint64_t first = 0, lost = 0;
    const std::size_t n = ring.read(buf.data(), 4096, &first, &lost);
    if (lost != 0) {
      d.first_frames.push_back(first);
      d.gaps.push_back(lost);
    }
    if (n != 0 || lost != 0) {
      d.samples.insert(d.samples.end(), buf.begin(), buf.begin() + static_cast<std::ptrdiff_t>(n * ring.channels()));
      d.next_frame = first + n;
      continue;
    }
    if (was_done || Clock::now() > deadline) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return d;
}

// ---------------------------------------------------------------- capture, bit-exact

struct FormatCase {
  SampleFormat format;
  std::uint32_t channels;
};

class AlsaCaptureFormats : public ::testing::TestWithParam<FormatCase> {};

TEST_P(AlsaCaptureFormats, ChirpThroughFilePcmIsBitExactAtItsFrames) {
  const auto [format, channels] = GetParam();
  TempDir dir;
  const std::size_t frames = 30000;  // not a multiple of the period: the last read is short
  const Encoded enc = encode(format, chirp(frames, channels));
  write_bytes(dir.file("in.raw"), enc.raw);
  write_text(dir.file("asound.conf"), file_pcm("filecap", dir.file("in.raw")));

  test::RecordingLogger log;
  AlsaSource src;
  src.open(capture_config("filecap", dir.file("asound.conf"), std::string(format_name(format)), channels, frames), log);
  EXPECT_EQ(src.setup().format, format);
  EXPECT_EQ(src.channels(), channels);
  EXPECT_EQ(src.sample_rate_hz(), kRate);
  EXPECT_TRUE(src.live());
  AudioRing ring(channels, 65536);
  src.start(ring);
  const Drained d = drain(ring, [&] { return src.finished(); });
  src.stop();
  EXPECT_EQ(src.error(), "");
  EXPECT_TRUE(d.gaps.empty());
  EXPECT_EQ(d.next_frame, frames);
  EXPECT_EQ(ring.frames_lost(), 0u);
  ASSERT_EQ(d.samples.size(), enc.expected.size());
  std::size_t mismatches = 0;
  for (std::size_t i = 0; i < d.samples.size(); ++i)
    if (std::memcmp(&d.samples[i], &enc.expected[i], sizeof(float)) != 0 && ++mismatches <= 5)
      ADD_FAILURE() << format_name(format) << " sample " << i << " (frame " << i / channels << "): got "
                    << d.samples[i] << " expected " << enc.expected[i];
  EXPECT_EQ(mismatches, 0u);
  EXPECT_EQ(src.counters().frames.load(), frames);
  EXPECT_EQ(src.counters().xruns.load(), 0u);  // `null` has no clock: it cannot overrun
  EXPECT_TRUE(log.contains("max_frames (30000) reached"));
}

INSTANTIATE_TEST_SUITE_P(EveryFormat, AlsaCaptureFormats,
                         ::testing::Values(FormatCase{SampleFormat::S16, 1}, FormatCase{SampleFormat::S16, 2},
                                           FormatCase{SampleFormat::S24, 1}, FormatCase{SampleFormat::S24_3, 2},
                                           FormatCase{SampleFormat::S32, 1}, FormatCase{SampleFormat::S32, 2},
                                           FormatCase{SampleFormat::Float, 1}, FormatCase{SampleFormat::Float, 2}),
                         [](const auto& info) {
                           return std::string(format_name(info.param.format)) + "_" +
                                  std::to_string(info.param.channels) + "ch";
                         });

TEST(AlsaCapture, AutoFormatPrefersFloatOnAPcmThatTakesEverything) {
  test::RecordingLogger log;
  AlsaSource src;
  src.open(capture_config("null", "", "auto", 2, 1000), log);
  EXPECT_EQ(src.setup().format, SampleFormat::Float);
  AudioRing ring(2, 4096);
  src.start(ring);
  const Drained d = drain(ring, [&] { return src.finished(); });
  src.stop();
  EXPECT_EQ(src.error(), "");
  EXPECT_EQ(d.next_frame, 1000u);  // `null` capture gives silence
  for (float v : d.samples) ASSERT_EQ(v, 0.0f);
}

// ---------------------------------------------------------------- malformed configuration

std::string open_error(const AlsaStreamConfig& c) {
  test::RecordingLogger log;
  AlsaSource src;
  try {
    src.open(c, log);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

TEST(AlsaCapture, UnknownPcmNameIsAClearError) {
  const std::string e = open_error(capture_config("locus_no_such_pcm", "", "s16", 1, 0));
  EXPECT_NE(e.find("alsa source: cannot open PCM 'locus_no_such_pcm' for capture"), std::string::npos) << e;
  EXPECT_NE(e.find("No such file or directory"), std::string::npos) << e;
  EXPECT_NE(e.find("Unknown PCM locus_no_such_pcm"), std::string::npos) << e;
}

TEST(AlsaCapture, MissingOrMalformedConfigFileIsAClearError) {
  TempDir dir;
  std::string e = open_error(capture_config("filecap", dir.file("absent.conf"), "s16", 1, 0));
  EXPECT_NE(e.find("config_file '" + dir.file("absent.conf") + "' cannot be read: No such file or directory"),
            std::string::npos)
      << e;
  write_text(dir.file("bad.conf"), "pcm.filecap { type file slave.pcm \"null\" \n");  // unterminated
  e = open_error(capture_config("filecap", dir.file("bad.conf"), "s16", 1, 0));
  EXPECT_NE(e.find("config_file '" + dir.file("bad.conf") + "' is not a valid ALSA configuration"), std::string::npos)
      << e;
  // A PCM whose infile does not exist names the file (libasound's message).
  write_text(dir.file("missing_in.conf"), file_pcm("filecap", dir.file("nope.raw")));
  e = open_error(capture_config("filecap", dir.file("missing_in.conf"), "s16", 1, 0));
  EXPECT_NE(e.find("cannot open PCM 'filecap' for capture: No such file or directory"), std::string::npos) << e;
  EXPECT_NE(e.find(dir.file("nope.raw")), std::string::npos) << e;
  // The same PCM with a readable infile opens.
  write_text(dir.file("ok.conf"), file_pcm("filecap", "/dev/zero"));
  AlsaStreamConfig c = capture_config("filecap", dir.file("ok.conf"), "s16", 1, 0);
  EXPECT_EQ(open_error(c), "");
}

// ---------------------------------------------------------------- playback at a scheduled frame

class AlsaPlaybackFormats : public ::testing::TestWithParam<SampleFormat> {};

TEST_P(AlsaPlaybackFormats, ScheduledClipLandsAtItsFrameBitExact) {
  const SampleFormat format = GetParam();
  TempDir dir;
  const std::string out = dir.file("out.raw");
  write_text(dir.file("asound.conf"),
             "pcm.fileplay {\n  type file\n  slave.pcm \"null\"\n  file \"" + out + "\"\n  format \"raw\"\n}\n");
  // A clip whose samples are exact in every format (k / 2^15), scheduled at a frame that is not a
  // period boundary.
  const std::uint64_t start = 12345;
  std::vector<float> clip(3000);
  const std::vector<double> x = chirp(clip.size(), 1, 0.7);
  for (std::size_t i = 0; i < clip.size(); ++i) clip[i] = static_cast<float>(std::llround(x[i] * 32767.0)) / 32768.0f;
  const std::uint32_t channels = 2;
  const std::uint64_t total = 20000;

  PlaybackScheduler scheduler(kRate);
  ASSERT_TRUE(scheduler.submit(clip, start));
  test::RecordingLogger log;
  AlsaSink sink;
  AlsaStreamConfig c = capture_config("fileplay", dir.file("asound.conf"), std::string(format_name(format)), channels,
                                      total);
  sink.open(c, log);
  EXPECT_EQ(sink.setup().format, format);
  sink.start(scheduler);
  const auto deadline = Clock::now() + std::chrono::seconds(30);
  while (!sink.finished() && Clock::now() < deadline) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  ASSERT_TRUE(sink.finished()) << "playback did not end";
  sink.stop();
  EXPECT_EQ(sink.error(), "");
  EXPECT_EQ(sink.xruns(), 0u);
  EXPECT_EQ(scheduler.frame(), total);
  EXPECT_EQ(scheduler.clips_played(), 1u);
  // Contract (playback.hpp): late = start already passed when the RT side took the clip. Not the case here.
  EXPECT_EQ(scheduler.late_clips(), 0u);

  const std::vector<unsigned char> bytes = read_bytes(out);
  const std::size_t bps = bytes_per_sample(format);
  ASSERT_EQ(bytes.size(), total * channels * bps) << "the file holds every frame played";
  std::vector<float> played(total * channels);
  raw_to_float(format, bytes.data(), played.data(), played.size());
  std::size_t bad = 0;
  for (std::uint64_t f = 0; f < total; ++f)
    for (std::uint32_t ch = 0; ch < channels; ++ch) {
      const float want = (f >= start && f < start + clip.size()) ? clip[f - start] : 0.0f;
      const float got = played[f * channels + ch];
      if (got != want && ++bad <= 5)
        ADD_FAILURE() << format_name(format) << " frame " << f << " ch " << ch << ": got " << got << " want " << want;
    }
  EXPECT_EQ(bad, 0u);
}

INSTANTIATE_TEST_SUITE_P(EveryFormat, AlsaPlaybackFormats,
                         ::testing::Values(SampleFormat::S16, SampleFormat::S24, SampleFormat::S24_3, SampleFormat::S32,
                                           SampleFormat::Float),
                         [](const auto& info) { return std::string(format_name(info.param)); });

// ---------------------------------------------------------------- device listing

TEST(AlsaDevices, ListsTheConfiguredPcmsWithoutCards) {
  const std::vector<DeviceInfo> devices = list_alsa_devices();
  bool null_pcm = false, jack_pcm = false;
  for (const DeviceInfo& d : devices) {
    EXPECT_EQ(d.backend, "alsa");
    EXPECT_FALSE(d.kind.empty());
    if (d.kind == "pcm" && d.id == "null") null_pcm = true;
    if (d.kind == "pcm" && d.id == "jack") jack_pcm = true;
    std::printf("[ alsa ] %s %s: %s\n", d.kind.c_str(), d.id.c_str(), d.description.c_str());
  }
  EXPECT_TRUE(null_pcm);
  EXPECT_TRUE(jack_pcm);  // libasound2-plugins (tools/install-deps.sh)
}

// ---------------------------------------------------------------- dummy jackd: rate refusal, pacing

/// A dummy jackd started for one test (no real-time scheduling), stopped by PID.
class Jackd {
 public:
  Jackd(const std::string& name, std::uint32_t rate, std::uint32_t period) : name_(name) {
    const std::string r = std::to_string(rate), p = std::to_string(period);
    std::vector<std::string> args{"jackd", "-n", name, "-r", "-d", "dummy", "-r", r, "-p", p};
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&fa, 2, "/dev/null", O_WRONLY, 0);
    if (posix_spawnp(&pid_, "jackd", &fa, nullptr, argv.data(), environ) != 0) pid_ = -1;
    posix_spawn_file_actions_destroy(&fa);
  }
  ~Jackd() {
    if (pid_ > 0) {
      ::kill(pid_, SIGTERM);
      for (int i = 0; i < 300; ++i) {
        if (::waitpid(pid_, nullptr, WNOHANG) == pid_) return;
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
      }
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  bool ready() const {
    if (pid_ <= 0) return false;
    const std::string cmd = "jack_wait -s " + name_ + " -w -t 10 >/dev/null 2>&1";
    return std::system(cmd.c_str()) == 0;
  }

 private:
  std::string name_;
  pid_t pid_ = -1;
};

TEST(AlsaJack, APcmThatCannotDoTheRateIsRefusedNamingTheRatesItOffers) {
  const std::string server = "locus_alsa_rate_" + std::to_string(::getpid());
  Jackd jackd(server, 48000, 256);
  ASSERT_TRUE(jackd.ready()) << "jackd did not start";
  ::setenv("JACK_DEFAULT_SERVER", server.c_str(), 1);
  TempDir dir;
  write_text(dir.file("asound.conf"), "pcm.jk { type jack capture_ports { 0 \"system:capture_1\" } }\n");
  const std::string e = open_error(capture_config("jk", dir.file("asound.conf"), "float", 1, 0));
  ::unsetenv("JACK_DEFAULT_SERVER");
  EXPECT_NE(e.find("PCM 'jk' cannot capture at exactly 44100 Hz: it offers 48000..48000 Hz"), std::string::npos) << e;
}

TEST(AlsaJack, CaptureIsPacedInRealTimeAndEveryFrameIsAccountedFor) {
  const std::string server = "locus_alsa_pace_" + std::to_string(::getpid());
  Jackd jackd(server, kRate, 1024);
  ASSERT_TRUE(jackd.ready()) << "jackd did not start";
  ::setenv("JACK_DEFAULT_SERVER", server.c_str(), 1);
  TempDir dir;
  // The jack PCM takes float only; `plug` converts to the s16 asked here.
  write_text(dir.file("asound.conf"),
             "pcm.jk { type plug slave.pcm { type jack capture_ports { 0 \"system:capture_1\" } } }\n");
  test::RecordingLogger log;
  AlsaSource src;
  AlsaStreamConfig c = capture_config("jk", dir.file("asound.conf"), "s16", 1, kRate);  // 1 s
  c.request.period_frames = 1024;
  c.stall_timeout_s = 5.0;
  src.open(c, log);
  AudioRing ring(1, 1 << 17);
  const auto t0 = Clock::now();
  src.start(ring);
  const Drained d = drain(ring, [&] { return src.finished(); }, 30.0);
  const double took_s = std::chrono::duration<double>(Clock::now() - t0).count();
  src.stop();
  ::unsetenv("JACK_DEFAULT_SERVER");
  EXPECT_EQ(src.error(), "");
  // The stream clock accounts for every frame: read + reported lost = max_frames.
  std::uint64_t lost = 0;
  for (auto g : d.gaps) lost += g;
  EXPECT_EQ(d.samples.size() + lost, static_cast<std::size_t>(kRate));
  EXPECT_EQ(d.next_frame, kRate);
  for (float v : d.samples) ASSERT_EQ(v, 0.0f);  // the dummy driver captures silence
  // Paced by jackd's clock: one second of audio takes about one second (generous bounds).
  EXPECT_GT(took_s, 0.7);
  EXPECT_LT(took_s, 10.0);
  std::printf("[ alsa ] jack-paced capture: 1 s of audio in %.2f s, %llu xruns, %llu frames lost\n", took_s,
              static_cast<unsigned long long>(src.counters().xruns.load()), static_cast<unsigned long long>(lost));
}

// ---------------------------------------------------------------- device loss (jackd stopped)
//
// A `type file` PCM never fails mid-stream (past its infile's end, or on a read error, it repeats
// stale frames), so the loss of a device is simulated by stopping the jackd a `jack` PCM captures
// from: the PCM stays "running" and gives no data, which stall_timeout_s turns into a device loss.

constexpr const char* kJackPcm =
    "pcm.jk { type plug slave.pcm { type jack capture_ports { 0 \"system:capture_1\" } } }\n";

AlsaStreamConfig loss_config(const std::string& config_file) {
  AlsaStreamConfig c = capture_config("jk", config_file, "s16", 1, 0);
  c.request.period_frames = 1024;
  c.stall_timeout_s = 0.3;
  c.retry_backoff_s = 0.1;
  c.retry_backoff_max_s = 0.4;
  return c;
}

bool wait_for(const std::function<bool()>& cond, double timeout_s) {
  const auto deadline = Clock::now() + std::chrono::duration<double>(timeout_s);
  while (!cond()) {
    if (Clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return true;
}

TEST(AlsaDeviceLoss, DeviceGoneRetriesThenEndsWithAClearErrorWithoutHanging) {
  const std::string server = "locus_alsa_loss_" + std::to_string(::getpid());
  auto jackd = std::make_unique<Jackd>(server, kRate, 1024);
  ASSERT_TRUE(jackd->ready()) << "jackd did not start";
  ::setenv("JACK_DEFAULT_SERVER", server.c_str(), 1);
  TempDir dir;
  write_text(dir.file("asound.conf"), kJackPcm);
  test::RecordingLogger log;
  AlsaSource src;
  AlsaStreamConfig c = loss_config(dir.file("asound.conf"));
  c.retry_max = 3;
  src.open(c, log);
  AudioRing ring(1, 1 << 18);
  src.start(ring);
  Drained d;
  std::thread reader([&] { d = drain(ring, [&] { return src.finished(); }, 60.0); });
  EXPECT_TRUE(wait_for([&] { return src.counters().frames.load() >= 8192; }, 20.0));
  const std::uint64_t before_loss = src.counters().frames.load();
  jackd.reset();  // the device goes away
  const auto t0 = Clock::now();
  const bool ended = wait_for([&] { return src.finished(); }, 30.0);
  const double took_s = std::chrono::duration<double>(Clock::now() - t0).count();
  reader.join();
  src.stop();
  ::unsetenv("JACK_DEFAULT_SERVER");
  ASSERT_TRUE(ended) << "no final error within 30 s";
  const std::string e = src.error();
  EXPECT_NE(e.find("alsa source: PCM 'jk' lost (no data for 0.3 s (stall_timeout_s)) at stream frame"),
            std::string::npos)
      << e;
  EXPECT_NE(e.find("not reopened after 3 attempt(s); last attempt: alsa source: cannot open PCM 'jk' for capture"),
            std::string::npos)
      << e;
  EXPECT_EQ(src.counters().device_losses.load(), 1u);
  EXPECT_EQ(src.counters().reconnects.load(), 0u);
  EXPECT_TRUE(log.contains("reopen attempt 3 failed", LogLevel::Warn));
  EXPECT_GE(src.counters().frames.load(), before_loss);
  // Stall (0.3 s) + backoffs (0.1 + 0.2 + 0.4 s) + three failed opens: seconds, not a hang.
  EXPECT_LT(took_s, 20.0);
  std::printf("[ alsa ] device loss -> final error %.2f s after jackd stopped: %s\n", took_s, e.c_str());
}

TEST(AlsaDeviceLoss, NoReopenWhenRetryMaxIsZero) {
  const std::string server = "locus_alsa_noretry_" + std::to_string(::getpid());
  auto jackd = std::make_unique<Jackd>(server, kRate, 1024);
  ASSERT_TRUE(jackd->ready()) << "jackd did not start";
  ::setenv("JACK_DEFAULT_SERVER", server.c_str(), 1);
  TempDir dir;
  write_text(dir.file("asound.conf"), kJackPcm);
  test::RecordingLogger log;
  AlsaSource src;
  AlsaStreamConfig c = loss_config(dir.file("asound.conf"));
  c.retry_max = 0;
  src.open(c, log);
  AudioRing ring(1, 1 << 18);
  src.start(ring);
  EXPECT_TRUE(wait_for([&] { return src.counters().frames.load() >= 4096; }, 20.0));
  jackd.reset();
  const bool ended = wait_for([&] { return src.finished(); }, 20.0);
  src.stop();
  ::unsetenv("JACK_DEFAULT_SERVER");
  ASSERT_TRUE(ended);
  EXPECT_NE(src.error().find("retry_max is 0: no reopen attempt"), std::string::npos) << src.error();
}

TEST(AlsaDeviceLoss, ADeviceThatComesBackResumesWithTheGapReportedAsLostFrames) {
  const std::string server = "locus_alsa_back_" + std::to_string(::getpid());
  auto jackd = std::make_unique<Jackd>(server, kRate, 1024);
  ASSERT_TRUE(jackd->ready()) << "jackd did not start";
  ::setenv("JACK_DEFAULT_SERVER", server.c_str(), 1);
  TempDir dir;
  write_text(dir.file("asound.conf"), kJackPcm);
  test::RecordingLogger log;
  AlsaSource src;
  AlsaStreamConfig c = loss_config(dir.file("asound.conf"));
  c.retry_max = 50;
  src.open(c, log);
  AudioRing ring(1, 1 << 20);
  src.start(ring);
  Drained d;
  std::atomic<bool> reading_done{false};
  std::thread reader([&] { d = drain(ring, [&] { return reading_done.load(); }, 120.0); });
  EXPECT_TRUE(wait_for([&] { return src.counters().frames.load() >= 8192; }, 20.0));
  jackd.reset();  // unplugged ...
  EXPECT_TRUE(wait_for([&] { return src.counters().device_losses.load() >= 1; }, 20.0));
  jackd = std::make_unique<Jackd>(server, kRate, 1024);  // ... and plugged in again
  ASSERT_TRUE(jackd->ready()) << "jackd did not restart";
  const bool back = wait_for([&] { return src.counters().reconnects.load() >= 1; }, 30.0);
  const std::uint64_t at_reconnect = src.counters().frames.load();
  EXPECT_TRUE(wait_for([&] { return src.counters().frames.load() >= at_reconnect + 8192; }, 20.0));
  src.stop();
  reading_done.store(true);
  reader.join();
  ::unsetenv("JACK_DEFAULT_SERVER");
  ASSERT_TRUE(back) << "not reopened after jackd came back";
  EXPECT_EQ(src.error(), "");
  // Every frame of the stream is accounted for: frames read + frames reported lost = stream clock.
  std::uint64_t lost = 0;
  for (auto g : d.gaps) lost += g;
  EXPECT_EQ(d.samples.size() + lost, d.next_frame);
  EXPECT_EQ(lost, ring.frames_lost());
  // The gap is reported where the data stopped, and lasts at least the stall timeout.
  ASSERT_GE(d.gaps.size(), 1u);
  const std::uint64_t gap_lost = src.counters().gap_frames_lost.load();
  EXPECT_GE(gap_lost, static_cast<std::uint64_t>(0.3 * kRate));
  EXPECT_LE(gap_lost, lost);
  EXPECT_TRUE(log.contains("reopened after"));
  std::printf("[ alsa ] reconnect: %zu gap(s), %llu frames lost (%llu in the device gap, %.2f s), %llu xruns\n",
              d.gaps.size(), static_cast<unsigned long long>(lost), static_cast<unsigned long long>(gap_lost),
              static_cast<double>(gap_lost) / kRate, static_cast<unsigned long long>(src.counters().xruns.load()));
}

TEST(AlsaJack, AnOverrunIsRecoveredCountedAndItsFramesReportedLost) {
  const std::string server = "locus_alsa_xrun_" + std::to_string(::getpid());
  Jackd jackd(server, kRate, 256);
  ASSERT_TRUE(jackd.ready()) << "jackd did not start";
  ::setenv("JACK_DEFAULT_SERVER", server.c_str(), 1);
  TempDir dir;
  write_text(dir.file("asound.conf"), kJackPcm);
  PcmRequest r;
  r.pcm = "jk";
  r.config_file = dir.file("asound.conf");
  r.format = "s16";
  r.period_frames = 256;
  r.periods = 4;
  Pcm pcm = Pcm::open(r);
  AudioRing ring(1, 1 << 20);
  AlsaCounters counters;
  SpscQueue<AlsaNotice> notices(16);
  std::atomic<bool> stop{false};
  CaptureLoop loop(pcm.get(), pcm.setup(), ring, counters, &notices, 0, 5.0, &stop);
  auto run_for = [&](double seconds) {
    const auto until = Clock::now() + std::chrono::duration<double>(seconds);
    while (Clock::now() < until) {
      const CaptureLoop::Status st = loop.step(20);
      ASSERT_NE(st, CaptureLoop::Status::DeviceLost) << alsa_error_text(loop.error());
    }
  };
  run_for(0.5);
  const std::uint64_t before = loop.produced();
  // The capture thread is late by far more than the buffer (4 x 256 frames = 23 ms): an overrun.
  const auto t_sleep = Clock::now();
  std::this_thread::sleep_for(std::chrono::milliseconds(400));
  const double slept_s = std::chrono::duration<double>(Clock::now() - t_sleep).count();
  run_for(0.5);
  ::unsetenv("JACK_DEFAULT_SERVER");
  EXPECT_GE(counters.xruns.load(), 1u);
  AlsaNotice n;
  ASSERT_TRUE(notices.try_pop(n)) << "no overrun notice";
  EXPECT_EQ(n.kind, AlsaNotice::Kind::Overrun);
  EXPECT_EQ(n.frame, before);
  // At least the time the thread slept, minus the buffer it could hold, was lost.
  EXPECT_GE(n.frames_lost, static_cast<std::uint64_t>((slept_s - 0.1) * kRate));
  // ... and not more than that time plus one step of the loop and the buffer (generous on a busy host).
  EXPECT_LE(n.frames_lost, static_cast<std::uint64_t>((slept_s + 0.2) * kRate));
  // The stream clock counts read + lost frames: it stays with the device's clock.
  EXPECT_EQ(loop.produced(), loop.frames_read() + ring.frames_lost());
  EXPECT_EQ(ring.frames_lost(), counters.xrun_frames_lost.load());
  std::printf("[ alsa ] overrun after a %.3f s stall: %llu xrun(s), %llu frames lost (%.3f s, timestamps %s)\n",
              slept_s, static_cast<unsigned long long>(counters.xruns.load()), static_cast<unsigned long long>(n.frames_lost),
              static_cast<double>(n.frames_lost) / kRate, n.timestamps_valid ? "of the PCM" : "of the host clock");
}

/// jackd's own frame counter (the "device clock" of a `jack` PCM), read through a JACK client.
class JackClock {
 public:
  explicit JackClock(const std::string& server) {
    jack_status_t status{};
    client_ = jack_client_open("locus_alsa_clock", static_cast<jack_options_t>(JackNoStartServer | JackServerName),
                               &status, server.c_str());
    if (client_ && jack_activate(client_) != 0) {
      jack_client_close(client_);
      client_ = nullptr;
    }
  }
  ~JackClock() {
    if (client_) {
      jack_deactivate(client_);
      jack_client_close(client_);
    }
  }
  bool ok() const { return client_ != nullptr; }
  std::uint64_t now() const { return jack_frame_time(client_); }

 private:
  jack_client_t* client_ = nullptr;
};

TEST(AlsaJack, AnUnderrunIsRecoveredAndSkippedSoThePlaybackClockKeepsTime) {
  const std::string server = "locus_alsa_urun_" + std::to_string(::getpid());
  Jackd jackd(server, kRate, 256);
  ASSERT_TRUE(jackd.ready()) << "jackd did not start";
  ::setenv("JACK_DEFAULT_SERVER", server.c_str(), 1);
  TempDir dir;
  write_text(dir.file("asound.conf"),
             "pcm.jkp { type plug slave.pcm { type jack playback_ports { 0 \"system:playback_1\" } } }\n");
  PcmRequest r;
  r.pcm = "jkp";
  r.config_file = dir.file("asound.conf");
  r.stream = SND_PCM_STREAM_PLAYBACK;
  r.format = "s16";
  r.period_frames = 256;
  r.periods = 4;
  Pcm pcm = Pcm::open(r);
  PlaybackScheduler scheduler(kRate);
  AlsaCounters counters;
  SpscQueue<AlsaNotice> notices(16);
  std::atomic<bool> stop{false};
  PlaybackLoop loop(pcm.get(), pcm.setup(), scheduler, counters, &notices, 0, 5.0, &stop);
  JackClock jack_clock(server);
  ASSERT_TRUE(jack_clock.ok()) << "cannot open a JACK client to read the device clock";
  std::uint64_t jack_first = 0;
  bool started = false;
  auto run_for = [&](double seconds) {
    const auto until = Clock::now() + std::chrono::duration<double>(seconds);
    while (Clock::now() < until) {
      const PlaybackLoop::Status st = loop.step(20);
      if (!started && snd_pcm_state(pcm.get()) == SND_PCM_STATE_RUNNING) {
        started = true;
        jack_first = jack_clock.now();
      }
      ASSERT_NE(st, PlaybackLoop::Status::DeviceLost) << alsa_error_text(loop.error());
    }
  };
  run_for(0.5);
  const std::uint64_t before = scheduler.frame();
  const auto t_sleep = Clock::now();
  std::this_thread::sleep_for(std::chrono::milliseconds(400));  // the device runs dry: an underrun
  const double slept_s = std::chrono::duration<double>(Clock::now() - t_sleep).count();
  run_for(0.5);
  const std::uint64_t frame = scheduler.frame();
  const double elapsed_s = static_cast<double>(jack_clock.now() - jack_first) / kRate;  // on the device clock
  ::unsetenv("JACK_DEFAULT_SERVER");
  EXPECT_GE(counters.xruns.load(), 1u);
  AlsaNotice n;
  ASSERT_TRUE(notices.try_pop(n)) << "no underrun notice";
  EXPECT_EQ(n.kind, AlsaNotice::Kind::Underrun);
  EXPECT_GE(n.frame, before);
  // The device was starved for the sleep minus the buffer it held: that much was skipped.
  EXPECT_GE(n.frames_lost, static_cast<std::uint64_t>((slept_s - 0.15) * kRate));
  EXPECT_LE(n.frames_lost, static_cast<std::uint64_t>((slept_s + 0.15) * kRate));
  // The playback clock (scheduler frame) stays with the device's (jackd's frame counter): without the
  // skip it would fall behind by the whole stall (0.4 s), with a double count run 0.4 s ahead. The
  // dummy driver's cycles jitter on this busy host (measured -0.12..+0.08 s over 1.3 s), and its pace
  // differs from the wall clock by a few %, hence the margins and the device clock as reference.
  const double ahead_s = static_cast<double>(frame) / kRate - elapsed_s;
  EXPECT_GT(ahead_s, -0.25);
  EXPECT_LT(ahead_s, 0.25);
  std::printf("[ alsa ] underrun after a %.3f s stall: %llu xrun(s), %llu frames skipped (%.3f s, timestamps %s); "
              "playback clock %.3f s ahead of the device clock after %.2f s\n",
              slept_s, static_cast<unsigned long long>(counters.xruns.load()),
              static_cast<unsigned long long>(n.frames_lost), static_cast<double>(n.frames_lost) / kRate,
              n.timestamps_valid ? "of the PCM" : "of the host clock", ahead_s, elapsed_s);
}

// ---------------------------------------------------------------- end to end: config -> pipeline

TEST(AlsaPipeline, ChirpCapturedThroughAConfigIsDetectedAtItsFrame) {
  // A node config names the `alsa` source with a private config_file; the `chirp` detector must find
  // a 2 -> 8 kHz, 40 ms chirp (its default template) at the frame where it was written into the file.
  TempDir dir;
  const std::size_t frames = 2 * kRate;
  const std::uint64_t at = 50000;
  std::vector<double> x(frames);
  std::uint64_t lcg = 12345;
  for (double& v : x) {  // deterministic noise at about -55 dBFS
    lcg = lcg * 6364136223846793005ull + 1442695040888963407ull;
    v = (static_cast<double>(lcg >> 11) * 0x1p-53 - 0.5) * 0.006;
  }
  const double d = 0.040, fade = 0.005, f0 = 2000.0, f1 = 8000.0;
  for (std::size_t i = 0; i < static_cast<std::size_t>(d * kRate); ++i) {
    const double t = static_cast<double>(i) / kRate;
    double w = 1.0;
    if (t < fade) w = 0.5 * (1.0 - std::cos(std::numbers::pi * t / fade));
    if (d - t < fade) w = 0.5 * (1.0 - std::cos(std::numbers::pi * (d - t) / fade));
    x[at + i] += 0.5 * w * std::sin(2.0 * std::numbers::pi * (f0 * t + (f1 - f0) * t * t / (2.0 * d)));
  }
  write_bytes(dir.file("in.raw"), encode(SampleFormat::S16, x).raw);
  write_text(dir.file("asound.conf"), file_pcm("filecap", dir.file("in.raw")));
  const std::string yaml = "sample_rate_hz: 44100\noutput: {path: \"" + dir.file("events.jsonl") +
                           "\"}\ndevices:\n  - id: A\n    audio:\n      source: alsa\n      ring_frames: 262144\n"
                           "      params: {pcm: filecap, config_file: \"" + dir.file("asound.conf") +
                           "\", format: s16, max_frames: " + std::to_string(frames) +
                           "}\n    detectors:\n      - plugin: chirp\n";
  Registry registry;
  register_builtins(registry);
  const Config config = load_config_string(yaml, "alsa.yaml", registry);
  std::vector<AudioDetection> found;
  std::vector<DeviceStats> stats;
  {
    Pipeline p(config, registry);
    std::mutex m;
    p.subscribe(EventType::AudioDetection, [&](const Event& e) {
      std::lock_guard lock(m);
      found.push_back(std::get<AudioDetection>(e));
    });
    p.start();
    EXPECT_TRUE(wait_for([&] { return p.finished(); }, 60.0)) << "the capture did not end";
    p.stop();
    stats = p.stats();
  }
  ASSERT_EQ(stats.size(), 1u);
  EXPECT_EQ(stats[0].frames_processed, frames);
  EXPECT_EQ(stats[0].frames_lost, 0u);
  EXPECT_EQ(stats[0].source_error, "");
  ASSERT_EQ(found.size(), 1u) << "one chirp in the file";
  EXPECT_NEAR(found[0].frame, static_cast<double>(at), 1.0);
  std::printf("[ alsa ] pipeline: chirp written at frame %llu detected at %.3f (snr %.1f dB)\n",
              static_cast<unsigned long long>(at), found[0].frame, found[0].snr_db);
}

}  // namespace
}  // namespace locus::hal::alsa
