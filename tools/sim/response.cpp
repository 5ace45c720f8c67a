// Transducer responses (response.hpp): RBJ cookbook equaliser biquads and random per-device responses.
#include "locus/sim/response.hpp"

#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>
#include <stdexcept>
#include <string>

namespace locus::sim {

namespace {

dsp::Biquad normalise(double b0, double b1, double b2, double a0, double a1, double a2) {
  dsp::Biquad q;
  q.b0 = b0 / a0;
  q.b1 = b1 / a0;
  q.b2 = b2 / a0;
  q.a1 = a1 / a0;
  q.a2 = a2 / a0;
  return q;
}

dsp::Biquad eq_biquad(const EqSection& e, double fs) {
  if (!(e.freq_hz > 0.0 && e.freq_hz < 0.5 * fs))
    throw std::invalid_argument("response: eq section frequency " + std::to_string(e.freq_hz) +
                                " Hz must be in (0, fs/2)");
  const double A = std::pow(10.0, e.gain_db / 40.0);
  const double w = 2.0 * std::numbers::pi * e.freq_hz / fs;
  const double c = std::cos(w), sn = std::sin(w);
  if (e.kind == EqSection::Kind::Peaking) {
    if (!(e.q > 0.0)) throw std::invalid_argument("response: peaking section q must be > 0");
    const double al = sn / (2.0 * e.q);
    return normalise(1.0 + al * A, -2.0 * c, 1.0 - al * A, 1.0 + al / A, -2.0 * c, 1.0 - al / A);
  }
  // high shelf, slope S = 1
  const double al = sn / 2.0 * std::sqrt(2.0);
  const double sA = 2.0 * std::sqrt(A) * al;
  return normalise(A * ((A + 1) + (A - 1) * c + sA), -2.0 * A * ((A - 1) + (A + 1) * c), A * ((A + 1) + (A - 1) * c - sA),
                   (A + 1) - (A - 1) * c + sA, 2.0 * ((A - 1) - (A + 1) * c), (A + 1) - (A - 1) * c - sA);
}

}  // namespace

std::vector<dsp::Biquad> design_response(const BandLimit& b, double fs) {
  std::vector<dsp::Biquad> sos;
  if (b.low_hz > 0.0) {
    auto s = dsp::butter_highpass(b.order, b.low_hz, fs);
    sos.insert(sos.end(), s.begin(), s.end());
  }
  if (b.high_hz > 0.0 && b.high_hz < 0.5 * fs) {
    auto s = dsp::butter_lowpass(b.order, b.high_hz, fs);
    sos.insert(sos.end(), s.begin(), s.end());
  }
  for (const auto& e : b.eq) sos.push_back(eq_biquad(e, fs));
  return sos;
}

double response_db(const BandLimit& b, double f, double fs) {
  const auto sos = design_response(b, fs);
  return 20.0 * std::log10(std::abs(dsp::sos_response(sos, f, fs)));
}

double ripple_peak_db(const BandLimit& b, double lo, double hi, double fs) {
  BandLimit peaks;
  for (const auto& e : b.eq)
    if (e.kind == EqSection::Kind::Peaking) peaks.eq.push_back(e);
  if (peaks.eq.empty()) return 0.0;
  const auto sos = design_response(peaks, fs);
  double worst = 0.0;
  constexpr int kPoints = 400;
  for (int i = 0; i < kPoints; ++i) {
    const double f = lo * std::pow(hi / lo, static_cast<double>(i) / (kPoints - 1));
    worst = std::max(worst, std::abs(20.0 * std::log10(std::abs(dsp::sos_response(sos, f, fs)))));
  }
  return worst;
}

BandLimit random_transducer_response(const BandLimit& edges, const TransducerSpread& sp, double fs, Rng& rng) {
  if (sp.ripple_sections < 2 || !(sp.ripple_min_db >= 0.0) || sp.ripple_max_db < sp.ripple_min_db ||
      !(sp.ripple_lo_hz > 0.0) || !(sp.ripple_hi_hz > sp.ripple_lo_hz) || !(sp.ripple_hi_hz < 0.5 * fs) ||
      !(sp.rolloff_min_hz > 0.0) || sp.rolloff_max_hz < sp.rolloff_min_hz || !(sp.rolloff_max_hz < 0.5 * fs) ||
      !(sp.rolloff_min_db >= 0.0) || sp.rolloff_max_db < sp.rolloff_min_db)
    throw std::invalid_argument("response: bad TransducerSpread (ranges must be ordered, within (0, fs/2), >= 2 sections)");
  BandLimit out = edges;
  out.eq.clear();
  const double split = std::clamp(12000.0, sp.ripple_lo_hz, sp.ripple_hi_hz);
  for (int i = 0; i < sp.ripple_sections; ++i) {
    EqSection e;
    e.kind = EqSection::Kind::Peaking;
    if (i < sp.ripple_sections - 2)
      e.freq_hz = sp.ripple_lo_hz * std::pow(split / sp.ripple_lo_hz, rng.uniform());
    else
      e.freq_hz = rng.uniform(split, sp.ripple_hi_hz);
    e.q = rng.uniform(0.7, 3.0);
    e.gain_db = rng.normal();
    out.eq.push_back(e);
  }
  // scale the gains until the largest |ripple| is the drawn level (dB responses are nearly linear in
  // the section gains for dB-sized gains: three rounds converge to < 1 %)
  const double target = rng.uniform(sp.ripple_min_db, sp.ripple_max_db);
  for (int round = 0; round < 4; ++round) {
    const double peak = ripple_peak_db(out, sp.ripple_lo_hz, sp.ripple_hi_hz, fs);
    if (!(peak > 0.0)) break;
    for (auto& e : out.eq) e.gain_db *= target / peak;
  }
  if (sp.rolloff) {
    EqSection shelf;
    shelf.kind = EqSection::Kind::HighShelf;
    shelf.freq_hz = rng.uniform(sp.rolloff_min_hz, sp.rolloff_max_hz);
    shelf.gain_db = -rng.uniform(sp.rolloff_min_db, sp.rolloff_max_db);
    out.eq.push_back(shelf);
  }
  return out;
}

}  // namespace locus::sim
