// RT-safety proof of the ALSA backend's inner loops (hal/alsa): CaptureLoop::step (snd_pcm_readi,
// conversion, AudioRing::write, including the ring-overrun path) and PlaybackLoop::step
// (PlaybackScheduler::render_interleaved, conversion, snd_pcm_writei) make no allocation, free or
// mutex lock of ours after warm-up, run through real libasound on `type file` PCMs (no sound card).
//
// libasound protects plugin PCMs (not hw PCMs) with a per-PCM mutex of its own (alsa-lib's
// "thread-safe API", LIBASOUND_THREAD_SAFE=0 turns it off). That mutex is only ever taken by our one
// audio thread, so it is uncontended and never blocks; the test counts those locks separately with a
// calibration run of bare snd_pcm_readi/writei calls and requires our loop to add none.
#include <gtest/gtest.h>
#include <alsa/asoundlib.h>
#include <stdlib.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "alsa/alsa_pcm.hpp"
#include "alsa/alsa_sink.hpp"
#include "alsa/alsa_source.hpp"
#include "locus/audio_ring.hpp"
#include "locus/playback.hpp"
#include "rt_hooks.hpp"

using locus::rt_hooks::RtSection;

namespace locus::hal::alsa {
namespace {

struct ConfigDir {
  std::string dir, conf;
  ConfigDir() {
    std::string tmpl = (std::filesystem::temp_directory_path() / "locus_rt_alsa_XXXXXX").string();
    dir = ::mkdtemp(tmpl.data()) ? tmpl : std::string();
    conf = dir + "/asound.conf";
    std::ofstream(conf) << "pcm.rtcap { type file slave.pcm \"null\" file \"/dev/null\" infile \"/dev/zero\" format "
                           "\"raw\" }\n"
                           "pcm.rtplay { type file slave.pcm \"null\" file \"/dev/null\" format \"raw\" }\n";
  }
  ~ConfigDir() {
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
  }
};

PcmRequest request(const ConfigDir& cd, const char* pcm, snd_pcm_stream_t stream, const char* format) {
  PcmRequest r;
  r.pcm = pcm;
  r.config_file = cd.conf;
  r.stream = stream;
  r.channels = 2;
  r.format = format;
  r.period_frames = 256;
  return r;
}

/// Locks libasound itself takes for `calls` bare reads/writes of one period (the calibration).
long bare_locks(snd_pcm_t* pcm, const PcmSetup& setup, bool capture, int calls) {
  std::vector<unsigned char> buf(setup.period_frames * setup.frame_bytes());
  for (int i = 0; i < 10; ++i)
    capture ? (void)snd_pcm_readi(pcm, buf.data(), setup.period_frames)
            : (void)snd_pcm_writei(pcm, buf.data(), setup.period_frames);
  RtSection rt;
  for (int i = 0; i < calls; ++i)
    capture ? (void)snd_pcm_readi(pcm, buf.data(), setup.period_frames)
            : (void)snd_pcm_writei(pcm, buf.data(), setup.period_frames);
  rt.end();
  return rt.locks();
}

TEST(RtSafety, AlsaCaptureLoopDoesNotAllocateOrLock) {
  ConfigDir cd;
  for (const char* format : {"s16", "s24_3", "float"}) {
    Pcm pcm = Pcm::open(request(cd, "rtcap", SND_PCM_STREAM_CAPTURE, format));
    AudioRing ring(2, 4096, 8);
    AlsaCounters counters;
    SpscQueue<AlsaNotice> notices(16);
    std::atomic<bool> stop{false};
    CaptureLoop loop(pcm.get(), pcm.setup(), ring, counters, &notices, 0, 0.0, &stop);
    std::vector<float> out(2 * 4096);
    for (int i = 0; i < 20; ++i) loop.step(20);  // warm-up: start, first reads
    ring.read(out.data(), 4096);
    const int kSteps = 2000;
    RtSection rt;
    for (int i = 0; i < kSteps; ++i) {
      loop.step(20);  // the ring fills up: the loss path (write_lost) runs too
      if (i % 40 == 0) ring.read(out.data(), 4096);
    }
    rt.end();
    const long locks = rt.locks();
    const long lib_locks = bare_locks(pcm.get(), pcm.setup(), true, kSteps);
    EXPECT_GT(loop.frames_read(), 256u * kSteps / 2) << format;
    EXPECT_GT(ring.overruns(), 0u) << format;
    EXPECT_EQ(rt.allocs(), 0) << format;
    EXPECT_EQ(rt.frees(), 0) << format;
    EXPECT_LE(locks, lib_locks) << format << ": the loop takes locks beyond libasound's own PCM mutex";
    std::printf("[ rt_alsa ] capture %s: %d steps, 0 allocs, %ld locks (libasound alone: %ld)\n", format, kSteps,
                locks, lib_locks);
  }
}

TEST(RtSafety, AlsaPlaybackLoopDoesNotAllocateOrLock) {
  ConfigDir cd;
  for (const char* format : {"s16", "s32", "float"}) {
    Pcm pcm = Pcm::open(request(cd, "rtplay", SND_PCM_STREAM_PLAYBACK, format));
    PlaybackScheduler scheduler(44100.0);
    // Clips active during the measured steps (submitted and reclaimed on the "main" side, outside).
    for (int k = 0; k < 8; ++k) ASSERT_TRUE(scheduler.submit(std::vector<float>(20000, 0.25f), 5000u + 60000u * k));
    AlsaCounters counters;
    SpscQueue<AlsaNotice> notices(16);
    std::atomic<bool> stop{false};
    PlaybackLoop loop(pcm.get(), pcm.setup(), scheduler, counters, &notices, 0, 0.0, &stop);
    for (int i = 0; i < 20; ++i) loop.step(20);
    const int kSteps = 2000;
    RtSection rt;
    for (int i = 0; i < kSteps; ++i) loop.step(20);
    rt.end();
    const long locks = rt.locks();
    const long lib_locks = bare_locks(pcm.get(), pcm.setup(), false, kSteps);
    EXPECT_GT(scheduler.clips_played(), 0u) << format;
    EXPECT_GT(loop.frames_played(), 256u * kSteps / 2) << format;
    EXPECT_EQ(rt.allocs(), 0) << format;
    EXPECT_EQ(rt.frees(), 0) << format;
    EXPECT_LE(locks, lib_locks) << format << ": the loop takes locks beyond libasound's own PCM mutex";
    std::printf("[ rt_alsa ] playback %s: %d steps, 0 allocs, %ld locks (libasound alone: %ld)\n", format, kSteps,
                locks, lib_locks);
    scheduler.reclaim();
  }
}

}  // namespace
}  // namespace locus::hal::alsa
