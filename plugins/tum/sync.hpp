// TUM live roles, the maths (docs/tum.md, "Live roles"): the loose synchronisation of the nodes' clocks
// from round trips of link messages (the paper's Wi-Fi RTT), the election of the two working devices
// (the pair with the closest clocks), the emission schedule, and the link messages that carry them.
// No threads, no link, no clock here: tum.cpp feeds these functions what it received and measured, so
// that the unit tests (tests/plugins/tum) check them on exact numbers.
//
// Clocks: a node's *host clock* (HostContext::clock, CLOCK_MONOTONIC on locusd). The offsets found are
// loose (an RTT of a few ms over MQTT, the paper's Wi-Fi gives tens): they only place each working
// device's emissions; the solve pairs the exchanges across clocks from the recordings (align_clocks,
// solver.hpp), which the µs of the tone arrivals need.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace locus::plugins::tum {

/// One round trip: the pinging node sends at t0 (its clock), the peer receives at t1 and replies at t2
/// (the peer's clock), the reply arrives at t3 (the pinging node's clock).
struct RoundTrip {
  double t0_s = 0.0, t1_s = 0.0, t2_s = 0.0, t3_s = 0.0;
  /// The peer's clock minus ours, assuming symmetric paths (NTP's θ).
  double offset_s() const noexcept { return 0.5 * ((t1_s - t0_s) + (t2_s - t3_s)); }
  /// Time on the wire both ways (NTP's δ): the offset is uncertain by ± half of it.
  double rtt_s() const noexcept { return (t3_s - t0_s) - (t2_s - t1_s); }
};

/// A peer's clock as estimated from several round trips.
struct ClockEstimate {
  double offset_s = 0.0;  ///< the peer's clock minus ours: median over the round trips
  double rtt_s = 0.0;     ///< median round-trip time
  double spread_s = 0.0;  ///< median absolute deviation of the offsets (their scatter)
  int samples = 0;
};

/// The median offset and RTT of the round trips (the last `max_samples` of them); nullopt with fewer
/// than `min_samples` or when a round trip is not causal (negative RTT: a clock jumped).
std::optional<ClockEstimate> estimate_clock(const std::vector<RoundTrip>& trips, int min_samples, int max_samples);

/// What one node reports on the link: whether it can be a working device (a speaker, an emitter and
/// two or more mics) and the median RTT to each peer it has measured.
struct SyncTable {
  std::string device;
  bool can_work = false;
  std::map<std::string, ClockEstimate> peers;
};

struct Election {
  std::string device1, device2;  ///< device1: the better ranked of the pair (elect())
  double rtt_s = 0.0;            ///< the pair's RTT (the larger of the two directions measured)
};

/// The working pair: of every pair of devices that both can work and have measured each other (in at
/// least one direction), the one with the smallest RTT (the paper's "closest clocks": the offset
/// between them is the least uncertain); pairs within `tie_s` of the smallest count as equal and the
/// best ranked pair wins, so that every node given the same tables makes the same choice. Rank: a
/// device's place in `order` (the config's `elect_order`), then every other device by id; a pair ranks
/// by its better device, then its other one. Device 1 is the pair's better ranked device. nullopt when
/// no pair qualifies.
std::optional<Election> elect(const std::vector<SyncTable>& tables, double tie_s, const std::vector<std::string>& order = {});

/// Emission k of working device 1 is at t0 + k · period on its host clock, device 2's `delay` later;
/// the first k whose emission (on device 1's clock) is at or after `after_s`.
std::int64_t next_emission_index(double t0_s, double period_s, double after_s);

/// Device 2's delay after device 1 at exchange k: `delay_s` + `jitter_s` · u_k, u_k in [0, 1) a fixed
/// pseudo-random sequence (splitmix64 of k). Why: the recordings pair the exchanges across clocks by the
/// interval between the two tones (align_clocks); a constant interval makes every round look alike and
/// the pairing may settle a whole period off (measured live: seed 3, 334 ms), as the paper's loose sync
/// and the speakers' random latencies never do.
double tone2_delay_s(double delay_s, double jitter_s, std::int64_t k);

/// A frame of a playback stream for a time on another clock: `anchor_frame` was the stream's frame at
/// `anchor_s` on this node's host clock, `peer_offset_s` = the other clock minus ours.
std::int64_t frame_for(double t_other_s, double peer_offset_s, double anchor_s, std::uint64_t anchor_frame, double rate_hz);

// ----------------------------------------------------------------------------- link messages (JSON)
//   <prefix>/sync/ping/<from>  {"type":"tum_ping","from":A,"seq":n,"t0":s}
//   <prefix>/sync/pong/<to>    {"type":"tum_pong","from":B,"to":A,"seq":n,"t0":s,"t1":s,"t2":s}
//   <prefix>/sync/table/<from> {"type":"tum_table","from":A,"can_work":true,
//                               "peers":{"B":{"offset":s,"rtt":s,"spread":s,"n":k},...}}
//   <prefix>/role              {"type":"tum_role","device1":A,"device2":B,"rtt":s,"t0":s,
//                               "period":s,"delay":s}   t0 on device 1's host clock

struct Ping {
  std::string from;
  std::uint64_t seq = 0;
  double t0_s = 0.0;
};
struct Pong {
  std::string from, to;
  std::uint64_t seq = 0;
  double t0_s = 0.0, t1_s = 0.0, t2_s = 0.0;
};
struct Role {
  Election election;
  double t0_s = 0.0, period_s = 0.0, delay_s = 0.0;
};

std::string topic_ping(std::string_view prefix, std::string_view from);
std::string topic_pong(std::string_view prefix, std::string_view to);
std::string topic_table(std::string_view prefix, std::string_view from);
std::string topic_role(std::string_view prefix);

std::string encode(const Ping& m);
std::string encode(const Pong& m);
std::string encode(const SyncTable& m);
std::string encode(const Role& m);

/// One decoded sync message (exactly one member set), or the reason it was refused. The topic's last
/// level must name the sender (ping, table) or the addressee (pong).
struct SyncDecoded {
  std::optional<Ping> ping;
  std::optional<Pong> pong;
  std::optional<SyncTable> table;
  std::optional<Role> role;
  std::string error;
};
/// Decodes a message under <prefix>/sync/... or <prefix>/role; error set for anything malformed.
SyncDecoded decode_sync(std::string_view prefix, std::string_view topic, std::string_view payload);

}  // namespace locus::plugins::tum
