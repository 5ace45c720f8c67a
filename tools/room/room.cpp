// `locus room` (room.hpp): the JACK client around RoomRenderer, the IMU feeder, the truth writer.
#include "locus/room/room.hpp"

#include <fcntl.h>
#include <jack/jack.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <thread>

#include <yaml-cpp/yaml.h>

#include "app.hpp"
#include "iio/fake_iio_tree.hpp"
#include "locus/scene/csv.hpp"
#include "locus/scene/truth.hpp"
#include "locus/sim/motion/imu.hpp"
#include "locus/sim/rng.hpp"

namespace locus::room {

namespace fs = std::filesystem;

namespace {

double monotonic_s() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// ------------------------------------------------------------------------------------ the JACK client

/// The room's JACK client: one input port per device speaker, one output port per microphone. The
/// process callback runs RoomRenderer::process on the port buffers and publishes the cycle's room
/// frame and CLOCK_MONOTONIC start (a seqlock) so that other threads can map room time to the host's.
class JackRoom {
 public:
  JackRoom(const RoomOptions& opts, const Layout& layout, RoomRenderer& renderer)
      : renderer_(renderer), spk_bufs_(layout.devices.size(), nullptr), mic_bufs_(renderer.total_mics(), nullptr) {
    jack_status_t st{};
    const auto options = static_cast<jack_options_t>(JackNoStartServer | JackUseExactName |
                                                     (opts.server.empty() ? 0 : JackServerName));
    jc_ = opts.server.empty() ? jack_client_open(opts.client_name.c_str(), options, &st)
                              : jack_client_open(opts.client_name.c_str(), options, &st, opts.server.c_str());
    const std::string server = opts.server.empty() ? "(default)" : "'" + opts.server + "'";
    if (jc_ == nullptr) {
      if (st & JackNameNotUnique) throw std::runtime_error("the JACK client name '" + opts.client_name + "' is already taken on server " + server);
      throw std::runtime_error("no JACK server " + server + " is running (start one: jackd -n NAME -d dummy -r 44100 -p 1024)");
    }
    const double rate = jack_get_sample_rate(jc_);
    if (std::abs(rate - layout.sample_rate_hz) > 0.5) {
      close();
      throw std::runtime_error("the JACK server runs at " + std::to_string(static_cast<int>(rate)) + " Hz but the layout's sample_rate is " +
                               std::to_string(static_cast<int>(layout.sample_rate_hz)) + " Hz");
    }
    for (std::size_t d = 0; d < layout.devices.size(); ++d) {
      const std::string& id = layout.devices[d].id;
      jack_port_t* p = jack_port_register(jc_, (id + "_spk").c_str(), JACK_DEFAULT_AUDIO_TYPE, JackPortIsInput, 0);
      if (p == nullptr) fail("cannot register port " + id + "_spk");
      spk_.push_back(p);
      for (std::size_t m = 0; m < renderer.mic_count(d); ++m) {
        jack_port_t* q = jack_port_register(jc_, (id + "_mic_" + std::to_string(m + 1)).c_str(), JACK_DEFAULT_AUDIO_TYPE,
                                            JackPortIsOutput, 0);
        if (q == nullptr) fail("cannot register port " + id + "_mic_" + std::to_string(m + 1));
        mic_.push_back(q);
        mic_device_.push_back(d);
      }
    }
    jack_set_process_callback(jc_, [](jack_nframes_t n, void* a) { return static_cast<JackRoom*>(a)->process(n); }, this);
    jack_set_xrun_callback(jc_, [](void* a) {
      static_cast<JackRoom*>(a)->xruns_.fetch_add(1, std::memory_order_relaxed);
      return 0;
    }, this);
    jack_on_info_shutdown(jc_, [](jack_status_t, const char*, void* a) {
      static_cast<JackRoom*>(a)->server_gone_.store(true, std::memory_order_release);
    }, this);
    if (jack_activate(jc_) != 0) fail("jack_activate failed");
  }
  ~JackRoom() { close(); }
  JackRoom(const JackRoom&) = delete;
  JackRoom& operator=(const JackRoom&) = delete;

  void close() {
    if (jc_ != nullptr) {
      jack_deactivate(jc_);
      jack_client_close(jc_);
      jc_ = nullptr;
    }
  }

  std::uint32_t buffer_size() const { return jc_ ? jack_get_buffer_size(jc_) : 0; }
  std::uint64_t xruns() const { return xruns_.load(std::memory_order_relaxed); }
  std::uint64_t skipped_frames() const { return skipped_.load(std::memory_order_relaxed); }
  bool server_gone() const { return server_gone_.load(std::memory_order_acquire); }
  /// CLOCK_MONOTONIC seconds of room frame 0 (NaN before the first cycle).
  double origin_monotonic_s() const { return origin_s_.load(std::memory_order_acquire); }
  /// The host's CLOCK_MONOTONIC time of room time t (from the latest cycle); NaN before the first.
  double monotonic_of(double t_room_s) const {
    for (;;) {
      const std::uint64_t s0 = seq_.load(std::memory_order_acquire);
      if (s0 & 1u) continue;
      const double f = cycle_frame_.load(std::memory_order_relaxed), m = cycle_mono_.load(std::memory_order_relaxed);
      std::atomic_thread_fence(std::memory_order_acquire);
      if (seq_.load(std::memory_order_relaxed) == s0) return m + (t_room_s - f / renderer_.sample_rate_hz());
    }
  }
  /// Devices whose ports are not all connected yet.
  std::vector<std::size_t> unconnected(std::size_t devices) const {
    std::vector<bool> ok(devices, true);
    for (std::size_t d = 0; d < devices; ++d)
      if (jack_port_connected(spk_[d]) <= 0) ok[d] = false;
    for (std::size_t i = 0; i < mic_.size(); ++i)
      if (jack_port_connected(mic_[i]) <= 0) ok[mic_device_[i]] = false;
    std::vector<std::size_t> out;
    for (std::size_t d = 0; d < devices; ++d)
      if (!ok[d]) out.push_back(d);
    return out;
  }

 private:
  [[noreturn]] void fail(const std::string& what) {
    close();
    throw std::runtime_error("room: " + what);
  }

  int process(jack_nframes_t n) noexcept {  // [RT]
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    const double now_us = static_cast<double>(ts.tv_sec) * 1e6 + static_cast<double>(ts.tv_nsec) * 1e-3;
    const jack_nframes_t frame_time = jack_last_frame_time(jc_);
    const double cycle_start_s = (static_cast<double>(jack_frames_to_time(jc_, frame_time)) + now_us - static_cast<double>(jack_get_time())) * 1e-6;
    if (!started_) {
      started_ = true;
      first_frame_time_ = frame_time;
      origin_s_.store(cycle_start_s, std::memory_order_release);
    }
    // Room frames are server frames since the first cycle: cycles the server ran without us are skipped.
    std::uint64_t have = renderer_.frames();
    std::uint64_t target = static_cast<std::uint32_t>(frame_time - first_frame_time_) + wraps_;
    if (target + (1ull << 31) < have) {  // the 32-bit frame time wrapped (every 27 h at 44.1 kHz)
      wraps_ += 1ull << 32;
      target += 1ull << 32;
    }
    if (target > have) {
      renderer_.skip(target - have);
      skipped_.fetch_add(target - have, std::memory_order_relaxed);
      have = target;
    }
    for (std::size_t d = 0; d < spk_.size(); ++d) spk_bufs_[d] = static_cast<const float*>(jack_port_get_buffer(spk_[d], n));
    for (std::size_t i = 0; i < mic_.size(); ++i) mic_bufs_[i] = static_cast<float*>(jack_port_get_buffer(mic_[i], n));
    seq_.fetch_add(1, std::memory_order_acq_rel);
    cycle_frame_.store(static_cast<double>(have), std::memory_order_relaxed);
    cycle_mono_.store(cycle_start_s, std::memory_order_relaxed);
    seq_.fetch_add(1, std::memory_order_release);
    renderer_.process(spk_bufs_.data(), mic_bufs_.data(), n);
    return 0;
  }

  RoomRenderer& renderer_;
  jack_client_t* jc_ = nullptr;
  std::vector<jack_port_t*> spk_, mic_;
  std::vector<std::size_t> mic_device_;
  std::vector<const float*> spk_bufs_;
  std::vector<float*> mic_bufs_;
  bool started_ = false;
  jack_nframes_t first_frame_time_ = 0;
  std::uint64_t wraps_ = 0;
  std::atomic<std::uint64_t> xruns_{0}, skipped_{0}, seq_{0};
  std::atomic<double> cycle_frame_{0.0}, cycle_mono_{std::numeric_limits<double>::quiet_NaN()};
  std::atomic<double> origin_s_{std::numeric_limits<double>::quiet_NaN()};
  std::atomic<bool> server_gone_{false};
};

// ------------------------------------------------------------------------------------ the IMUs

/// A layout trajectory seen on room time: layout time = room time − the layout's start (before the
/// start, the first pose).
class RoomTimeTrajectory final : public sim::Trajectory {
 public:
  RoomTimeTrajectory(std::shared_ptr<const sim::Trajectory> inner, const RoomRenderer& r) : inner_(std::move(inner)), r_(r) {}
  sim::Pose pose(double t_room_s) const override {
    const double start = r_.layout_start_s();
    return inner_->pose(std::isfinite(start) ? t_room_s - start : -1e9);
  }
  bool is_static() const override { return inner_->is_static(); }

 private:
  std::shared_ptr<const sim::Trajectory> inner_;
  const RoomRenderer& r_;
};

/// One thread writing every device's IMU scans into its fake IIO device at imu_rate_hz: sample j is the
/// phone IMU model (sim::motion::PhoneImu) of the device's trajectory at room time j / rate, stamped
/// with the host's CLOCK_MONOTONIC time of that instant, written once that instant has passed. A
/// device's FIFO is opened (non-blocking) once its node reads it; a full FIFO drops the scan (counted).
class ImuFeeder {
 public:
  ImuFeeder(const RoomOptions& opts, const Layout& layout, const RoomRenderer& renderer, const JackRoom& jack)
      : jack_(jack), rate_(opts.imu_rate_hz) {
    if (opts.magnetometer) {  // run_room checked that the layout has the field
      const auto& m = *layout.scene.truth->magnetic_field_world_ut;
      field_ut_ = Eigen::Vector3d(m[0], m[1], m[2]);
    }
    for (std::size_t d = 0; d < layout.devices.size(); ++d) {
      Dev dev;
      dev.id = layout.devices[d].id;
      dev.tree = std::make_unique<iio_fake::FakeIioTree>((fs::path(opts.out_dir) / "iio" / dev.id).string());
      iio_fake::FakeIioTree::ImuOptions io;
      char freq[32];
      std::snprintf(freq, sizeof freq, "%.6f", opts.imu_rate_hz);
      io.sampling_frequency = freq;
      io.timestamp_clock = "realtime";  // the kernel's default; the node's `iio` source switches it to monotonic
      io.magn = opts.magnetometer;
      dev.tree->add_imu(0, io);
      dev.fifo = dev.tree->path("dev/iio:device0");
      dev.accel_scale = std::stod(io.accel_scale);
      dev.gyro_scale = std::stod(io.gyro_scale);
      dev.magn_scale_ut = std::stod(io.magn_scale) * 100.0;  // Gauss per LSB -> µT per LSB
      sim::motion::PhoneImuConfig ic;  // the simulator's consumer 6-axis part (amil family values)
      ic.rate_hz = opts.imu_rate_hz;
      ic.magnetometer = opts.magnetometer;  // noise and hard iron: the simulator's phone defaults
      ic.gyro_noise_density = 1.6e-4;
      ic.accel_bias_std_mps2 = 0.04;
      ic.gyro_bias_std_radps = 0.004;
      ic.accel_scale_std = 0.004;
      ic.gyro_scale_std = 0.004;
      ic.stamp_jitter_std_s = 0.0;  // the stamp is the host's clock at the sample
      ic.scale_errors(opts.imu_error_scale);
      dev.imu = std::make_unique<sim::motion::PhoneImu>(ic);
      dev.rng = sim::Rng::derive(opts.renderer.seed, "room/imu/" + dev.id);
      dev.traj = std::make_unique<RoomTimeTrajectory>(layout.devices[d].trajectory, renderer);
      devs_.push_back(std::move(dev));
    }
    ::signal(SIGPIPE, SIG_IGN);  // a node that goes away: EPIPE, not the end of the room
  }
  ~ImuFeeder() { stop(); }

  std::string root(std::size_t d) const { return devs_[d].tree->root(); }
  void start() { thread_ = std::thread([this] { run(); }); }
  void stop() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
    for (auto& d : devs_)
      if (d.fd >= 0) ::close(d.fd), d.fd = -1;
  }
  std::uint64_t written(std::size_t d) const { return devs_[d].written.load(); }
  std::uint64_t dropped(std::size_t d) const { return devs_[d].dropped.load(); }

 private:
  struct Dev {
    std::string id, fifo;
    std::unique_ptr<iio_fake::FakeIioTree> tree;
    std::unique_ptr<sim::motion::PhoneImu> imu;
    std::unique_ptr<RoomTimeTrajectory> traj;
    sim::Rng rng;
    double accel_scale = 1.0, gyro_scale = 1.0, magn_scale_ut = 1.0;
    int fd = -1;
    std::atomic<std::uint64_t> written{0}, dropped{0};
    Dev() = default;
    Dev(Dev&& o) noexcept
        : id(std::move(o.id)), fifo(std::move(o.fifo)), tree(std::move(o.tree)), imu(std::move(o.imu)), traj(std::move(o.traj)),
          rng(o.rng), accel_scale(o.accel_scale), gyro_scale(o.gyro_scale), magn_scale_ut(o.magn_scale_ut), fd(o.fd), written(o.written.load()), dropped(o.dropped.load()) {}
  };

  void run() {
    // wait for the room's first cycle (the time base)
    while (!stop_ && !std::isfinite(jack_.monotonic_of(0.0))) std::this_thread::sleep_for(std::chrono::milliseconds(5));
    if (stop_) return;
    // Room time -> CLOCK_MONOTONIC: each cycle's estimate (JACK's DLL) jitters by milliseconds on a
    // loaded machine; a real IMU's stamps do not. The offset is smoothed (time constant ~2 s) so that
    // the stamps follow the server's clock without its jitter, and kept increasing.
    double offset = jack_.monotonic_of(0.0);
    double last_stamp = -1e300;
    const double t_first = std::max(0.0, monotonic_s() - offset);
    for (std::int64_t j = static_cast<std::int64_t>(std::ceil(t_first * rate_)); !stop_; ++j) {
      const double t = static_cast<double>(j) / rate_;
      offset += std::min(1.0, 0.5 / rate_) * (jack_.monotonic_of(0.0) - offset);
      const double mono = std::max(t + offset, last_stamp + 0.25 / rate_);
      const double wait = mono - monotonic_s();
      if (wait > 0) std::this_thread::sleep_for(std::chrono::duration<double>(std::min(wait, 0.05)));
      if (monotonic_s() < mono) {
        --j;  // not yet (slept at most 50 ms to notice stop)
        continue;
      }
      last_stamp = mono;
      const auto ns = static_cast<std::int64_t>(std::llround(mono * 1e9));
      for (auto& d : devs_) {
        if (d.fd < 0) d.fd = ::open(d.fifo.c_str(), O_WRONLY | O_NONBLOCK | O_CLOEXEC);  // ENXIO: no reader yet
        const sim::ImuReading r = d.imu->sample(*d.traj, field_ut_, t, d.rng);  // every device's model advances
        if (d.fd < 0) continue;
        const Eigen::Vector3d mag = r.mag_ut.value_or(Eigen::Vector3d::Zero());
        const std::int16_t raw[9]{iio_fake::to_lsb(r.accel_mps2.x(), d.accel_scale), iio_fake::to_lsb(r.accel_mps2.y(), d.accel_scale),
                                  iio_fake::to_lsb(r.accel_mps2.z(), d.accel_scale), iio_fake::to_lsb(r.gyro_radps.x(), d.gyro_scale),
                                  iio_fake::to_lsb(r.gyro_radps.y(), d.gyro_scale), iio_fake::to_lsb(r.gyro_radps.z(), d.gyro_scale),
                                  iio_fake::to_lsb(mag.x(), d.magn_scale_ut), iio_fake::to_lsb(mag.y(), d.magn_scale_ut),
                                  iio_fake::to_lsb(mag.z(), d.magn_scale_ut)};
        const std::vector<std::uint8_t> scan = iio_fake::pack_s16_scan(raw, field_ut_ ? 9 : 6, ns);  // the magn channels last
        const ssize_t w = ::write(d.fd, scan.data(), scan.size());
        if (w == static_cast<ssize_t>(scan.size())) {
          d.written.fetch_add(1);
        } else if (w < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
          d.dropped.fetch_add(1);
        } else {  // the reader went away: wait for the next one
          ::close(d.fd);
          d.fd = -1;
        }
      }
    }
  }

  const JackRoom& jack_;
  double rate_;
  std::optional<Eigen::Vector3d> field_ut_;  ///< world frame; set: the IMUs have a magnetometer
  std::vector<Dev> devs_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

// ------------------------------------------------------------------------------------ the truth

std::map<std::string, double> read_node_origins(const std::string& path, std::vector<std::string>& warnings) {
  std::map<std::string, double> out;
  if (path.empty()) return out;
  std::ifstream in(path);
  if (!in) {
    warnings.push_back("--node-origins " + path + ": cannot read it");
    return out;
  }
  int line_no = 0;
  for (std::string line; std::getline(in, line);) {
    ++line_no;
    if (line.empty() || line[0] == '#' || line.rfind("device,", 0) == 0) continue;
    const auto comma = line.find(',');
    double v = 0.0;
    try {
      std::size_t used = 0;
      if (comma == std::string::npos) throw std::invalid_argument("no comma");
      v = std::stod(line.substr(comma + 1), &used);
      if (comma + 1 + used != line.size() || !std::isfinite(v)) throw std::invalid_argument("trailing");
    } catch (const std::exception&) {
      warnings.push_back(path + ":" + std::to_string(line_no) + ": expected 'device,seconds' (CLOCK_MONOTONIC of its audio frame 0), got '" + line + "'");
      continue;
    }
    out[line.substr(0, comma)] = v;
  }
  return out;
}

void write_truth(const RoomOptions& opts, const Layout& layout, const RoomRenderer& r, double origin_mono_s,
                 const std::vector<Onset>& onsets, const JackRoom& jack, std::vector<std::string>& warnings) {
  const fs::path out(opts.out_dir);
  const double start = r.layout_start_s();
  const bool started = std::isfinite(start);
  // truth.csv: every device's trajectory on room time, sorted by t.
  std::vector<scene::TruthRow> rows;
  auto row = [&](const std::string& id, double t, const sim::Pose& p) {
    scene::TruthRow tr;
    tr.t_s = t;
    tr.id = id;
    tr.position_m = {p.position_m.x(), p.position_m.y(), p.position_m.z()};
    tr.q_wxyz = {p.attitude.w(), p.attitude.x(), p.attitude.y(), p.attitude.z()};
    rows.push_back(tr);
  };
  for (const auto& d : layout.devices) {
    if (!started || d.trajectory->is_static() || d.times_s.empty()) {
      row(d.id, 0.0, d.trajectory->pose(layout.t_begin_s));
      continue;
    }
    // the poses the room rendered (the eased trajectory) at the layout's own row times
    if (start + d.times_s.front() > 0.0) row(d.id, 0.0, d.trajectory->pose(d.times_s.front()));
    for (double tau : d.times_s)
      if (start + tau >= 0.0) row(d.id, start + tau, d.trajectory->pose(tau));
  }
  std::stable_sort(rows.begin(), rows.end(), [](const scene::TruthRow& a, const scene::TruthRow& b) { return a.t_s < b.t_s; });
  {
    scene::TruthCsvWriter w((out / "truth.csv").string());
    for (const auto& tr : rows) w.write(tr);
  }
  // Emissions (onsets on the speaker ports) and their direct arrivals at every microphone.
  {
    std::ofstream e(out / "room_emissions.csv");
    std::ofstream a(out / "room_arrivals.csv");
    e.precision(10);
    a.precision(10);
    e << "t_true,id,frame\n";
    a << "t_emission,source,receiver,mic,t_arrival,distance_m\n";
    for (const Onset& o : onsets) {
      const double te = static_cast<double>(o.frame) / r.sample_rate_hz();
      e << te << ',' << layout.devices[o.device].id << ',' << o.frame << '\n';
      for (std::size_t rx = 0; rx < layout.devices.size(); ++rx)
        for (std::size_t m = 0; m < r.mic_count(rx); ++m) {
          const double ta = r.direct_arrival_s(o.device, te, rx, m);
          a << te << ',' << layout.devices[o.device].id << ',' << layout.devices[rx].id << ',' << m << ',' << ta << ','
            << r.distance_m(o.device, rx, m, ta) << '\n';
        }
    }
    if (!e || !a) throw std::runtime_error("cannot write " + (out / "room_emissions.csv").string());
  }
  // scene.yaml: the layout's devices, the clocks of the nodes, the environment plus the room's facts.
  const std::map<std::string, double> origins = read_node_origins(opts.node_origins, warnings);
  scene::Scene sc;
  sc.dir = out.string();
  sc.name = "room: " + (layout.scene.name.empty() ? layout.dir : layout.scene.name);
  sc.sample_rate_hz = layout.sample_rate_hz;
  sc.speed_of_sound_mps = layout.speed_of_sound_mps;
  YAML::Node env = layout.scene.environment_yaml.empty() ? YAML::Node(YAML::NodeType::Map) : YAML::Load(layout.scene.environment_yaml);
  if (!env.IsMap()) env = YAML::Node(YAML::NodeType::Map);
  env["truth_emissions"] = YAML::Node();  // the simulator's schedule is not this run's
  env.remove("truth_emissions");
  env["room_layout"] = layout.dir;
  env["room_origin_monotonic_s"] = origin_mono_s;
  env["room_layout_start_s"] = started ? start : -1.0;
  env["room_emissions"] = "room_emissions.csv";
  env["room_arrivals"] = "room_arrivals.csv";
  env["room_imu"] = opts.imu;  // every device had a fake IIO IMU (locus eval: a walker's IMU stayed on its node)
  env["room_jack_xruns"] = jack.xruns();
  env["room_skipped_frames"] = jack.skipped_frames();
  YAML::Emitter em;
  em << YAML::Flow << env;
  sc.environment_yaml = em.c_str();
  scene::Truth truth;
  truth.trajectories = "truth.csv";
  for (std::size_t d = 0; d < layout.devices.size(); ++d) {
    const auto& ld = layout.devices[d];
    if (ld.emitter) {  // a beacon: back under emitters, at its position (its anchor when it had one)
      scene::EmitterSpec e;
      e.id = ld.id;
      e.emits = ld.emits;
      if (const scene::EmitterSpec* orig = layout.scene.find_emitter(ld.id); orig != nullptr && orig->anchor_position_m)
        e.anchor_position_m = orig->anchor_position_m;
      sc.emitters.push_back(e);
      continue;
    }
    scene::DeviceSpec spec;
    spec.id = ld.id;
    for (const auto& m : ld.mics_body_m) spec.mics_m.push_back({m.x(), m.y(), m.z()});
    if (ld.speaker_body_m) spec.speaker_m = scene::Vec3{ld.speaker_body_m->x(), ld.speaker_body_m->y(), ld.speaker_body_m->z()};
    spec.emits = ld.emits;
    sc.devices.push_back(spec);
    // local = (t − c_d)/r_d + (room origin − node origin) on the node's audio frames
    const double k = 1.0 + r.skew_ppm(d) * 1e-6;
    double origin_shift = 0.0;
    const auto it = origins.find(ld.id);
    if (it != origins.end()) {
      origin_shift = origin_mono_s - it->second;
    } else if (!opts.node_origins.empty()) {
      warnings.push_back("device " + ld.id + ": no audio origin in " + opts.node_origins +
                         ": its truth clock assumes its node's frame 0 is the room's (off by when it started)");
    }
    truth.clocks[ld.id] = scene::ClockTruth{-r.clock_offset_s(d) * k + origin_shift, r.skew_ppm(d)};
  }
  sc.truth = truth;
  scene::write_scene_yaml(sc);
}

}  // namespace

std::vector<double> parse_skew(const std::string& spec, const Layout& layout) {
  std::vector<double> out(layout.devices.size(), 0.0);
  if (spec.empty() || spec == "none") return out;
  if (spec == "scene") {
    for (std::size_t d = 0; d < layout.devices.size(); ++d)
      if (layout.devices[d].clock) out[d] = layout.devices[d].clock->skew_ppm;
    return out;
  }
  std::stringstream ss(spec);
  for (std::string item; std::getline(ss, item, ',');) {
    const auto eq = item.find('=');
    if (eq == std::string::npos)
      throw std::invalid_argument("--skew: '" + item + "': expected none, scene or DEV=PPM[,DEV=PPM...]");
    const std::string id = item.substr(0, eq);
    std::size_t d = 0;
    while (d < layout.devices.size() && layout.devices[d].id != id) ++d;
    if (d == layout.devices.size()) throw std::invalid_argument("--skew: no device '" + id + "' in the layout");
    try {
      std::size_t used = 0;
      out[d] = std::stod(item.substr(eq + 1), &used);
      if (eq + 1 + used != item.size()) throw std::invalid_argument("trailing");
    } catch (const std::exception&) {
      throw std::invalid_argument("--skew: '" + item + "': expected a number of ppm after '='");
    }
  }
  return out;
}

int run_room(const RoomOptions& opts) {
  const sigset_t stop_signals = app::block_stop_signals();

  Layout layout;
  RendererConfig rc = opts.renderer;
  try {
    layout = load_layout(opts.layout_dir);
    rc.skew_ppm = parse_skew(opts.skew, layout);
    if (!rc.room_size_m) rc.room_size_m = layout.room_size_m;
    if (!(opts.imu_rate_hz >= 1.0 && opts.imu_rate_hz <= 2000.0)) throw std::invalid_argument("--imu-rate-hz: expected 1..2000 Hz");
    if (opts.magnetometer && !opts.imu) throw std::invalid_argument("--magnetometer needs the IMUs (not with --no-imu)");
    if (opts.magnetometer && (!layout.scene.truth || !layout.scene.truth->magnetic_field_world_ut))
      throw std::invalid_argument("--magnetometer: " + opts.layout_dir +
                                  "/scene.yaml has no truth.magnetic_field_world (the field the magnetometers read)");
  } catch (const std::exception& e) {
    std::cerr << "locus room: " << e.what() << "\n";
    return app::kExitBadConfig;
  }
  std::error_code ec;
  fs::create_directories(opts.out_dir, ec);
  if (ec) {
    std::cerr << "locus room: cannot create " << opts.out_dir << ": " << ec.message() << "\n";
    return app::kExitFailure;
  }
  jack_set_error_function([](const char*) {});
  jack_set_info_function([](const char*) {});
  std::unique_ptr<RoomRenderer> renderer;
  std::unique_ptr<JackRoom> jack;
  std::unique_ptr<ImuFeeder> imu;
  try {
    renderer = std::make_unique<RoomRenderer>(layout, rc);
  } catch (const std::invalid_argument& e) {
    std::cerr << "locus room: " << e.what() << "\n";
    return app::kExitBadConfig;
  }
  std::vector<Onset> onsets;
  std::vector<std::string> warnings;
  try {
    jack = std::make_unique<JackRoom>(opts, layout, *renderer);
    if (jack->buffer_size() > rc.max_block_frames)
      throw std::runtime_error("the JACK period (" + std::to_string(jack->buffer_size()) + " frames) is longer than the room's block (" +
                               std::to_string(rc.max_block_frames) + ")");
    if (opts.imu) {
      imu = std::make_unique<ImuFeeder>(opts, layout, *renderer, *jack);
      imu->start();
    }
    std::cout << "room: " << layout.devices.size() << " devices of " << opts.layout_dir << " on JACK client '" << opts.client_name
              << "' (period " << jack->buffer_size() << " frames); ports " << opts.client_name << ":<id>_spk, " << opts.client_name
              << ":<id>_mic_<k>" << (opts.imu ? "; IIO roots " + (fs::path(opts.out_dir) / "iio").string() + "/<id>" : std::string())
              << "\n"
              << std::flush;
    const auto t_begin = std::chrono::steady_clock::now();
    bool waiting_reported = false;
    int signal_number = 0;
    for (;;) {
      Onset o;
      while (renderer->pop_onset(o)) onsets.push_back(o);
      if (jack->server_gone()) throw std::runtime_error("the JACK server went away");
      const double t_room = static_cast<double>(renderer->frames()) / renderer->sample_rate_hz();
      if (!std::isfinite(renderer->layout_start_s())) {
        const auto missing = jack->unconnected(layout.devices.size());
        const double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_begin).count();
        if (missing.empty() || waited > opts.start_timeout_s) {
          if (!missing.empty()) {
            std::string ids;
            for (std::size_t d : missing) ids += " " + layout.devices[d].id;
            warnings.push_back("started after " + std::to_string(static_cast<int>(opts.start_timeout_s)) +
                               " s without every device connected (missing:" + ids + ")");
            std::cerr << "locus room: warning: " << warnings.back() << "\n";
          }
          renderer->start_layout_at(t_room + opts.lead_in_s);
          std::cout << "room: every device connected; the layout starts at room time " << renderer->layout_start_s()
                    << " s (in " << opts.lead_in_s << " s) and ends " << (layout.t_end_s - layout.t_begin_s) << " s later\n"
                    << std::flush;
        } else if (!waiting_reported && waited > 5.0) {
          waiting_reported = true;
          std::cout << "room: waiting for " << missing.size() << " device(s) to connect\n" << std::flush;
        }
      } else if (opts.stop_after_s && t_room > renderer->layout_start_s() + (layout.t_end_s - layout.t_begin_s) + *opts.stop_after_s) {
        break;
      }
      timespec timeout{0, 50'000'000};
      const int sig = sigtimedwait(&stop_signals, nullptr, &timeout);
      if (sig > 0) {
        signal_number = sig;
        break;
      }
    }
    (void)signal_number;
    if (imu) imu->stop();
    Onset o;
    while (renderer->pop_onset(o)) onsets.push_back(o);
    const double origin = jack->origin_monotonic_s();
    const double t_room = static_cast<double>(renderer->frames()) / renderer->sample_rate_hz();
    jack->close();
    write_truth(opts, layout, *renderer, origin, onsets, *jack, warnings);
    std::cout << "room: stopped after " << t_room << " s of room time: " << jack->xruns() << " xruns, " << jack->skipped_frames()
              << " frames skipped, " << onsets.size() << " emissions, " << renderer->path_blocks() << " path-blocks rendered, "
              << renderer->clipped() << " samples clipped";
    if (imu) {
      std::uint64_t w = 0, dr = 0;
      for (std::size_t d = 0; d < layout.devices.size(); ++d) w += imu->written(d), dr += imu->dropped(d);
      std::cout << ", " << w << " IMU scans written (" << dr << " dropped)";
    }
    std::cout << "; truth in " << opts.out_dir << "\n";
    for (const auto& w : warnings) std::cerr << "locus room: warning: " << w << "\n";
  } catch (const std::exception& e) {
    if (imu) imu->stop();
    std::cerr << "locus room: " << e.what() << "\n";
    return app::kExitFailure;
  }
  return app::kExitOk;
}

}  // namespace locus::room
