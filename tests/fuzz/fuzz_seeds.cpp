// Writes the seed inputs of the `link` fuzz target into DIR (./run fuzz does this before fuzzing):
// valid messages of every built-in localizer's link protocol, made by the plugins' own encoders, a
// signed one, and a few near misses. The other targets are seeded from files (tests/fuzz/seed_corpus.sh).
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>

#include "amil/messages.hpp"
#include "auth/message_auth.hpp"
#include "locble/messages.hpp"
#include "montage/messages.hpp"
#include "tum/messages.hpp"

namespace amil = locus::plugins::amil;
namespace tum = locus::plugins::tum;
namespace montage = locus::plugins::montage;

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s DIR\n", argv[0]);
    return 2;
  }
  const std::string dir = argv[1];
  int n = 0;
  const auto seed = [&](char selector, const std::string& topic, const std::string& payload) {
    std::ofstream(dir + "/seed-" + std::to_string(n++), std::ios::binary) << selector << topic << '\n' << payload;
  };
  amil::ArrivalMessage a;
  a.listener = "L01";
  a.seq = 3;
  a.frame = 123456.25;
  a.sample_rate_hz = 44100;
  a.snr_db = 21.5;
  a.confidence = 0.8;
  a.envelope_frame = 123455.5;
  a.carrier_period = 2.2;
  seed('\0', amil::topic_arrival("amil", "L01"), amil::encode(a));
  seed('\0', amil::topic_done("amil", "L01"), amil::encode(amil::DoneMessage{"L01", 5}));
  seed('\0', amil::topic_hello("amil", "L01"), amil::encode(amil::HelloMessage{"L01", 1, 0.05}));
  seed('\0', "amil/arrivals/L02", amil::encode(a));  // topic and payload disagree
  tum::ObsMessage o;
  o.device = "B";
  o.seq = 7;
  o.mics_m = {{0.07, 0, 0}, {-0.07, 0, 0}};
  o.speaker_m = tum::Vec3a{0, 0.02, 0};
  o.q_wxyz = std::array<double, 4>{1, 0, 0, 0};
  o.moving = true;
  o.t1_s = {1.25, NAN};
  o.t2_s = {1.5, 1.5001};
  seed('\1', tum::topic_obs("tum", "B"), tum::encode(o));
  locus::plugins::locble::TargetMotion tm;
  tm.address = {0xAA, 0xBB, 0xCC, 0xDD, 0xEE, 0x01};
  tm.t_s = 3.5;
  tm.east_m = 1.25;
  tm.north_m = -0.5;
  seed('\3', "locble/motion/T1", locus::plugins::locble::encode(tm));
  montage::RoundMessage r;
  r.device = "W1";
  r.tau_own_s = 0.5;
  r.self_m = 0.12;
  r.arrivals = {{"W2", 0.0123}, {"W3", -0.0045}};
  seed('\4', montage::topic_round("montage", "W1"), montage::encode(r));
  montage::StepMessage st;
  st.device = "W1";
  st.tau_s = 1.25;
  st.t_s = 11.25;
  st.stride_m = 0.7;
  st.heading_rad = 1.5;
  st.offset_rad = -0.1;
  st.offset_valid = true;
  seed('\5', montage::topic_step("montage", "W1"), montage::encode(st));
  seed('\6', montage::topic_progress("montage", "W1"), montage::encode(montage::ProgressMessage{"W1", 2.0}));
  locus::linkauth::MessageAuthenticator auth("fuzz-site-key-0123456789abcdef", "L01", 30.0);
  seed('\2', "amil/arrivals/L01", auth.sign("amil/arrivals/L01", amil::encode(a), 1.8e9));
  seed('\2', "amil/arrivals/L01", amil::encode(a));
  return 0;
}
