// The malformed corpus: every file is generated here and each case asserts the exact message,
// including the file and line:column (text) or byte offset (WAV). Messages are part of the format's
// public contract (docs/scene-format.md, "Errors").
#include <gtest/gtest.h>

#include "locus/scene/streams.hpp"
#include "scene_test_util.hpp"

using namespace locus;
using namespace locus::scene;
using namespace locus::scene::test;

namespace {

const char* const kHead = "format: locus-scene/1\nsample_rate: 48000\nspeed_of_sound: 343\n";

struct YamlCase {
  const char* name;
  std::string yaml;
  std::string expect;  // "{F}" stands for the scene.yaml path
};

std::string subst(std::string s, const std::string& f) {
  for (std::size_t p; (p = s.find("{F}")) != std::string::npos;) s.replace(p, 3, f);
  return s;
}

}  // namespace

TEST(SceneCorpus, SceneYaml) {
  const std::string H = kHead;
  const std::vector<YamlCase> cases = {
      {"bad format string", "format: locus-scene/2\nsample_rate: 48000\nspeed_of_sound: 343\ndevices: []\n",
       "{F}:1:9: format: expected 'locus-scene/1', got 'locus-scene/2'"},
      {"missing format", "sample_rate: 48000\nspeed_of_sound: 343\ndevices: []\n",
       "{F}:1:1: missing required key 'format' (expected 'locus-scene/1')"},
      {"missing sample_rate", "format: locus-scene/1\nspeed_of_sound: 343\ndevices: []\n",
       "{F}:1:1: missing required key 'sample_rate' (expected the audio rate in Hz)"},
      {"negative sample_rate", "format: locus-scene/1\nsample_rate: -1\nspeed_of_sound: 343\ndevices: []\n",
       "{F}:2:14: sample_rate: expected a rate > 0 Hz, got -1"},
      {"non-numeric sample_rate", "format: locus-scene/1\nsample_rate: fast\nspeed_of_sound: 343\ndevices: []\n",
       "{F}:2:14: sample_rate: expected a number, got 'fast'"},
      {"no speed of sound", "format: locus-scene/1\nsample_rate: 48000\ndevices: []\n",
       "{F}:1:1: missing required key 'speed_of_sound' (m/s) or 'temperature_c' (°C)"},
      {"missing devices", H, "{F}:1:1: missing required key 'devices' (expected a list of devices)"},
      {"duplicate id", H + "devices:\n  - id: A\n  - id: A\n",
       "{F}:6:9: devices[1].id: duplicate id 'A' (first declared at line 5)"},
      {"duplicate id device/emitter", H + "devices:\n  - id: A\nemitters:\n  - id: A\n    emits: []\n",
       "{F}:7:9: emitters[0].id: duplicate id 'A' (first declared at line 5)"},
      {"bad id chars", H + "devices:\n  - id: phone A\n",
       "{F}:5:9: devices[0].id: invalid id 'phone A' (expected letters, digits, '_' or '-' only)"},
      {"id too long", H + "devices:\n  - id: abcdefghijabcdefghijabcdefghij123\n",
       "{F}:5:9: devices[0].id: id 'abcdefghijabcdefghijabcdefghij123' is longer than 31 characters"},
      {"missing id", H + "devices:\n  - mics: [[0, 0, 0]]\n",
       "{F}:5:5: devices[0]: missing required key 'id' (expected an id [A-Za-z0-9_-]+)"},
      {"mic row of 2", H + "devices:\n  - id: A\n    mics:\n      - [0, 0, 0]\n      - [0.1, 0]\n",
       "{F}:8:9: devices[0].mics[1]: expected a row of 3 numbers [x, y, z], got 2 elements"},
      {"mic non-numeric", H + "devices:\n  - id: A\n    mics: [[0, 0, zero]]\n",
       "{F}:6:19: devices[0].mics[0][2]: expected a number, got 'zero'"},
      {"speaker not a list", H + "devices:\n  - id: A\n    speaker: 1\n",
       "{F}:6:14: devices[0].speaker: expected 3 numbers [x, y, z], got '1'"},
      {"lfm missing f1", H + "devices:\n  - id: A\n    emits:\n      - {type: lfm, f0: 2000, duration: 0.04}\n",
       "{F}:7:9: devices[0].emits[0]: missing required key 'f1' (expected 'f1' for type lfm)"},
      {"lfm zero duration",
       H + "devices:\n  - id: A\n    emits:\n      - {type: lfm, f0: 1, f1: 2, duration: 0, fade: 0.006}\n",
       "{F}:7:45: devices[0].emits[0].duration: value 0 out of range (expected > 0 s)"},
      {"amplitude out of range",
       H + "devices:\n  - id: A\n    emits:\n      - {type: lfm, f0: 1, f1: 2, duration: 0.01, amplitude: 2}\n",
       "{F}:7:62: devices[0].emits[0].amplitude: value 2 out of range (expected 0..1)"},
      {"emits entry without type", H + "devices:\n  - id: A\n    emits:\n      - {f0: 1}\n",
       "{F}:7:9: devices[0].emits[0]: missing required key 'type' (expected lfm, gold, multitone, ble or a project type)"},
      {"gold unlisted degree",
       H + "emitters:\n  - id: G\n    emits: [{type: gold, degree: 8, index: 0, carrier: 0, chip_samples: 1}]\ndevices: []\n",
       "{F}:6:34: emitters[0].emits[0].degree: degree 8 has no preferred pair (expected 5, 6, 7, 9, 10 or 11, or give 'chips')"},
      {"gold bad chips",
       H + "emitters:\n  - id: G\n    emits: [{type: gold, degree: 3, index: 0, carrier: 0, chip_samples: 1, chips: \"1012\"}]\n"
           "devices: []\n",
       "{F}:6:83: emitters[0].emits[0].chips: expected only '0' and '1', got '2' at position 3"},
      {"gold index out of range",
       H + "emitters:\n  - id: G\n    emits: [{type: gold, degree: 5, index: 33, carrier: 0, chip_samples: 1}]\ndevices: []\n",
       "{F}:6:44: emitters[0].emits[0].index: value 33 out of range (expected 0..32)"},
      {"gold chip_samples not an integer",
       H + "emitters:\n  - id: G\n    emits: [{type: gold, degree: 5, index: 1, carrier: 0, chip_samples: 1.5}]\ndevices: []\n",
       "{F}:6:73: emitters[0].emits[0].chip_samples: expected an integer, got '1.5'"},
      {"multitone empty tones",
       H + "emitters:\n  - id: M\n    emits: [{type: multitone, tones_hz: [], duration: 0.05}]\ndevices: []\n",
       "{F}:6:41: emitters[0].emits[0].tones_hz: expected a non-empty list of frequencies in Hz, got a list"},
      {"ble bad address",
       H + "emitters:\n  - id: T\n    emits: [{type: ble, address: \"C4:2C:03:3A:2C\", tx_power_dbm: -59, interval_s: 0.1}]\n"
           "devices: []\n",
       "{F}:6:34: emitters[0].emits[0].address: expected a BLE address AA:BB:CC:DD:EE:FF (hex), got 'C4:2C:03:3A:2C'"},
      {"ble missing interval",
       H + "emitters:\n  - id: T\n    emits: [{type: ble, address: \"C4:2C:03:3A:2C:A1\", tx_power_dbm: -59}]\ndevices: []\n",
       "{F}:6:13: emitters[0].emits[0]: missing required key 'interval_s' (expected 'interval_s' for type ble)"},
      {"emitter without emits", H + "devices: []\nemitters:\n  - id: T\n",
       "{F}:6:5: emitters[0]: missing required key 'emits' (expected a list of signal entries)"},
      {"missing referenced file", H + "devices:\n  - id: A\n    mics: [[0, 0, 0]]\n    audio: A/audio.wav\n",
       "{F}:7:12: devices[0].audio: file 'A/audio.wav' not found (expected {D}/A/audio.wav)"},
      {"audio without mics", H + "devices:\n  - id: A\n    audio: scene.yaml\n",
       "{F}:5:5: devices[0]: device has 'audio' but no 'mics' (expected one mic row per audio channel)"},
      {"anchor without position", H + "devices:\n  - id: A\n    anchor: {pos: [1, 2, 3]}\n",
       "{F}:6:13: devices[0].anchor: missing required key 'position' (expected position: [x, y, z] in metres)"},
      {"clock of unknown device", H + "devices:\n  - id: A\ntruth:\n  clocks:\n    B: {offset_s: 1}\n",
       "{F}:8:5: truth.clocks: 'B' is not a device id (expected one of the devices)"},
      {"clock offset not a number", H + "devices:\n  - id: A\ntruth:\n  clocks:\n    A: {offset_s: soon}\n",
       "{F}:8:19: truth.clocks.A.offset_s: expected a number, got 'soon'"},
      {"yaml syntax error", H + "devices: [\n",
       "{F}:5:1: YAML syntax error: end of sequence flow not found"},
      {"top level not a map", "- a\n- b\n",
       "{F}:1:1: expected a mapping at the top level (format, sample_rate, devices, ...), got a list"},
      {"several issues at once",
       "format: x\nsample_rate: 0\nspeed_of_sound: 343\ndevices:\n  - id: A\n    mics: [[0, 0]]\n  - id: A\n",
       "{F}:1:9: format: expected 'locus-scene/1', got 'x'\n"
       "{F}:2:14: sample_rate: expected a rate > 0 Hz, got 0\n"
       "{F}:6:12: devices[0].mics[0]: expected a row of 3 numbers [x, y, z], got 2 elements\n"
       "{F}:7:9: devices[1].id: duplicate id 'A' (first declared at line 5)"},
  };
  int n = 0;
  for (const auto& c : cases) {
    TempDir tmp;
    const std::string dir = tmp / ("case" + std::to_string(n++));
    write_file(dir + "/scene.yaml", c.yaml);
    std::string expect = subst(c.expect, dir + "/scene.yaml");
    for (std::size_t p; (p = expect.find("{D}")) != std::string::npos;) expect.replace(p, 3, dir);
    EXPECT_EQ(scene_error([&] { load_scene(dir); }), expect) << "case: " << c.name << "\n" << c.yaml;
  }
  EXPECT_GE(cases.size(), 30u);
  TempDir tmp;
  EXPECT_EQ(scene_error([&] { load_scene(tmp / "nope"); }),
            tmp / "nope/scene.yaml" + ": no such file (scene directory '" + (tmp / "nope") + "' not found)");
}

TEST(SceneCorpus, CsvFiles) {
  struct CsvCase {
    const char* name;
    std::string text;
    int kind;  // 0 imu, 1 ble, 2 sync, 3 truth
    std::string expect;
  };
  const std::string imu_h = "t,ax,ay,az,gx,gy,gz\n";
  const std::vector<CsvCase> cases = {
      {"imu non-monotonic t", imu_h + "0.1,0,0,9.8,0,0,0\n0.3,0,0,9.8,0,0,0\n0.2,0,0,9.8,0,0,0\n", 0,
       "{F}:4:1: column 't': time 0.2 is before 0.3 on line 3 (rows must be in non-decreasing t)"},
      {"imu missing column", "t,ax,ay,az,gx,gz\n", 0,
       "{F}:1:1: missing required column 'gy' (header has: t, ax, ay, az, gx, gz)"},
      {"imu non-numeric cell", imu_h + "0.1,0,0,9.8,abc,0,0\n", 0,
       "{F}:2:13: column 'gx': expected a number, got 'abc'"},
      {"imu empty cell", imu_h + "0.1,0,,9.8,0,0,0\n", 0, "{F}:2:7: column 'ay': expected a number, got an empty field"},
      {"imu too few fields", imu_h + "0.1,0,0,9.8,0,0\n", 0, "{F}:2:1: expected 7 fields (as in the header), got 6"},
      {"imu partial mag columns", "t,ax,ay,az,gx,gy,gz,mx,my\n", 0,
       "{F}:1:1: columns mx, my, mz must be given together (found 2 of 3)"},
      {"imu half-empty mag row", "t,ax,ay,az,gx,gy,gz,mx,my,mz\n0,0,0,0,0,0,0,1,,3\n", 0,
       "{F}:2:17: column 'my': expected a number, got an empty field"},
      {"imu value out of float range", imu_h + "0,1e39,0,0,0,0,0\n", 0,
       "{F}:2:3: column 'ax': value 1e+39 is out of float range"},
      {"empty file", "", 0, "{F}:1:1: empty file (expected a header row)"},
      {"duplicate header", "t,ax,t\n", 0, "{F}:1:6: duplicate column name 't' in the header"},
      {"empty header name", "t,,ax\n", 0, "{F}:1:3: empty column name in the header (column 2)"},
      {"unterminated quote", imu_h + "0.1,\"0,0,9.8,0,0,0\n", 0,
       "{F}:2:5: unterminated quoted field (expected a closing '\"' before the end of the file)"},
      {"quote inside field", imu_h + "0.1,0\"1,0,9.8,0,0,0\n", 0,
       "{F}:2:6: quote inside an unquoted field (expected the whole field quoted, RFC 4180)"},
      {"text after closing quote", imu_h + "\"0.1\"x,0,0,9.8,0,0,0\n", 0,
       "{F}:2:6: expected ',' or the end of the line after a closing quote, got 'x'"},
      {"blank line inside", imu_h + "0.1,0,0,9.8,0,0,0\n\n0.2,0,0,9.8,0,0,0\n", 0,
       "{F}:3:1: blank line inside the data (blank lines are allowed only at the end of the file)"},
      {"ble bad address", "t,address,rssi\n0.5,C4:2C:03:3A:2C:G1,-60\n", 1,
       "{F}:2:5: column 'address': expected an address AA:BB:CC:DD:EE:FF (hex), got 'C4:2C:03:3A:2C:G1'"},
      {"ble missing rssi", "t,address\n", 1, "{F}:1:1: missing required column 'rssi' (header has: t, address)"},
      {"ble bad channel", "t,address,rssi,channel\n0.5,C4:2C:03:3A:2C:A1,-60,12\n", 1,
       "{F}:2:27: column 'channel': channel 12, expected 37, 38, 39 or 0 (unknown)"},
      {"ble non-integer channel", "t,address,rssi,channel\n0.5,C4:2C:03:3A:2C:A1,-60,37.5\n", 1,
       "{F}:2:27: column 'channel': expected an integer, got '37.5'"},
      {"sync empty source", "t,source\n0.5,\n", 2, "{F}:2:5: column 'source': expected a sender id, got an empty field"},
      {"sync long source", "t,source\n0.5,abcdefghijabcdefghijabcdefghij12\n", 2,
       "{F}:2:5: column 'source': sender id 'abcdefghijabcdefghijabcdefghij12' is longer than 31 characters"},
      {"truth unsorted", "t,id,x,y,z,qw,qx,qy,qz\n1,A,0,0,0,1,0,0,0\n0.5,B,0,0,0,1,0,0,0\n", 3,
       "{F}:3:1: column 't': time 0.5 is before 1 on line 2 (rows must be sorted by t)"},
      {"truth zero quaternion", "t,id,x,y,z,qw,qx,qy,qz\n1,A,0,0,0,0,0,0,0\n", 3,
       "{F}:2:11: column 'qw': quaternion (qw,qx,qy,qz) has norm 0, expected 1 (within 1e-3)"},
      {"truth missing id cell", "t,id,x,y,z,qw,qx,qy,qz\n1,,0,0,0,1,0,0,0\n", 3,
       "{F}:2:3: column 'id': expected an id, got an empty field"},
  };
  int n = 0;
  for (const auto& c : cases) {
    TempDir tmp;
    const std::string p = tmp / ("c" + std::to_string(n++) + ".csv");
    write_file(p, c.text);
    const std::string got = scene_error([&] {
      switch (c.kind) {
        case 0: {
          ImuCsvReader r(p, "A");
          ImuSample s;
          while (r.next(s)) {
          }
          break;
        }
        case 1: {
          BleCsvReader r(p, "A");
          BleAdvertisement a;
          while (r.next(a)) {
          }
          break;
        }
        case 2: {
          SyncCsvReader r(p, "A");
          RadioSync s;
          while (r.next(s)) {
          }
          break;
        }
        default: {
          TruthTrajectories::load(p);
        }
      }
    });
    EXPECT_EQ(got, subst(c.expect, p)) << "case: " << c.name;
  }
  TempDir tmp;
  EXPECT_EQ(scene_error([&] { CsvReader r(tmp / "missing.csv"); }),
            tmp / "missing.csv" + ": no such file (expected a CSV file)");
}

TEST(SceneCorpus, WavFiles) {
  struct WavCase {
    const char* name;
    std::string bytes;
    std::string expect;
  };
  auto with = [](auto f) {
    RawWav w;
    w.data = std::string(8, '\0');
    f(w);
    return build_wav(w);
  };
  const std::string good = with([](RawWav&) {});
  std::string bad_magic = good;
  bad_magic.replace(0, 4, "RIFX");
  std::string bad_wave = good;
  bad_wave.replace(8, 4, "AVI ");
  std::string data_first = "RIFF" + std::string("\x24\x00\x00\x00", 4) + "WAVEdata" + std::string(4, '\0');
  const std::vector<WavCase> cases = {
      {"wrong RIFF magic", bad_magic, "{F}: byte 0: expected 'RIFF', got 'RIFX' (not a RIFF/WAVE file)"},
      {"wrong WAVE magic", bad_wave, "{F}: byte 8: expected 'WAVE', got 'AVI '"},
      {"not audio at all", "ID3\x03 some mp3 bytes here", "{F}: byte 0: expected 'RIFF', got 'ID3\\x03' (not a RIFF/WAVE file)"},
      {"truncated header", good.substr(0, 8), "{F}: byte 8: truncated header: file ends after 8 bytes (expected a 12-byte RIFF/WAVE header)"},
      {"truncated before fmt", good.substr(0, 16),
       "{F}: byte 12: truncated header: expected a chunk header ('fmt '), file ends at byte 16"},
      {"truncated fmt body", good.substr(0, 30),
       "{F}: byte 20: truncated header: fmt chunk declares 16 bytes, file ends at byte 30"},
      {"no data chunk", good.substr(0, 36), "{F}: byte 36: truncated header: expected a chunk header ('data'), file ends at byte 36"},
      {"data before fmt", data_first, "{F}: byte 12: 'data' chunk before the 'fmt ' chunk (expected 'fmt ' first)"},
      {"unsupported format tag (ADPCM)", with([](RawWav& w) { w.tag = 2; w.bits = 4; w.block_align = 1; }),
       "{F}: byte 20: unsupported format tag 0x0002 (expected 0x0001 PCM, 0x0003 IEEE float or 0xFFFE extensible)"},
      {"unsupported PCM width", with([](RawWav& w) { w.bits = 8; }),
       "{F}: byte 34: PCM with 8 bits per sample, expected 16, 24 or 32"},
      {"float64", with([](RawWav& w) { w.tag = 3; w.bits = 64; }),
       "{F}: byte 34: IEEE float with 64 bits per sample, expected 32 (float64 is not supported)"},
      {"extensible with A-law sub-format", with([](RawWav& w) { w.tag = 0xFFFE; w.sub_tag = 6; }),
       "{F}: byte 44: unsupported sub-format 0x0006 (expected 0x0001 PCM or 0x0003 IEEE float)"},
      {"zero channels", with([](RawWav& w) { w.channels = 0; w.block_align = 0; }),
       "{F}: byte 22: channel count 0, expected >= 1"},
      {"zero rate", with([](RawWav& w) { w.rate = 0; }), "{F}: byte 24: sample rate 0, expected > 0"},
      {"bad block align", with([](RawWav& w) { w.channels = 2; w.block_align = 2; }),
       "{F}: byte 32: block align 2, expected 4 (channels x bytes per sample)"},
      {"oversized odd chunk before data",
       with([](RawWav& w) { w.extra_chunks = std::string("LIST\xFF\x00\x00\x00", 8); }),
       "{F}: byte 36: truncated header: chunk 'LIST' declares 255 bytes, file ends at byte 60 (expected a 'data' chunk)"},
  };
  int n = 0;
  for (const auto& c : cases) {
    TempDir tmp;
    const std::string p = tmp / ("c" + std::to_string(n++) + ".wav");
    write_file(p, c.bytes);
    EXPECT_EQ(scene_error([&] { WavReader r(p); }), subst(c.expect, p)) << "case: " << c.name;
  }
  TempDir tmp;
  EXPECT_EQ(scene_error([&] { WavReader r(tmp / "none.wav"); }),
            tmp / "none.wav" + ": no such file (expected a RIFF/WAVE audio file)");
}
