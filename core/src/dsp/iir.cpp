// Butterworth SOS design (zpk route as scipy.signal.butter), DF2T cascade, filtfilt.
#include "locus/dsp/iir.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>
#include "locus/numbers.hpp"

namespace locus::dsp {
namespace {

using cd = std::complex<double>;

enum class Band { low, high, pass, stop };

struct Zpk {
  std::vector<cd> z, p;
  double k = 1.0;
};

void check_common(int order, double fs, const char* what) {
  if (order < 1 || order > 64)
    throw std::invalid_argument(std::string(what) + ": order must be in 1..64, got " + std::to_string(order));
  if (!(fs > 0.0) || !std::isfinite(fs))
    throw std::invalid_argument(std::string(what) + ": sample_rate_hz must be > 0, got " + std::to_string(fs));
}

void check_edge(double f, double fs, const char* what, const char* name) {
  if (!(f > 0.0) || !(f < fs / 2.0))
    throw std::invalid_argument(std::string(what) + ": " + name + " must be in (0, fs/2 = " +
                                std::to_string(fs / 2.0) + ") Hz, got " + std::to_string(f));
}

// Analog Butterworth prototype (cutoff 1 rad/s): poles -exp(j·pi·m/(2N)), m = -N+1, -N+3, ..., N-1.
std::vector<cd> prototype_poles(int n) {
  std::vector<cd> p;
  p.reserve(static_cast<std::size_t>(n));
  for (int m = -n + 1; m < n; m += 2) {
    cd v = -std::exp(cd(0.0, kPi * m / (2.0 * n)));
    if (m == 0) v = cd(-1.0, 0.0);
    p.push_back(v);
  }
  return p;
}

cd prod_neg(const std::vector<cd>& v) {
  cd r(1.0, 0.0);
  for (const cd& x : v) r *= -x;
  return r;
}

Zpk analog_design(int n, Band band, double w1, double w2) {
  Zpk out;
  std::vector<cd> p = prototype_poles(n);
  const int degree = n;  // prototype has no zeros
  switch (band) {
    case Band::low:
      for (cd& x : p) x *= w1;
      out.p = p;
      out.k = std::pow(w1, degree);
      break;
    case Band::high:
      for (cd& x : p) x = w1 / x;
      out.k = std::real(cd(1.0, 0.0) / prod_neg(prototype_poles(n)));
      out.p = p;
      out.z.assign(static_cast<std::size_t>(degree), cd(0.0, 0.0));
      break;
    case Band::pass: {
      const double bw = w2 - w1, wo = std::sqrt(w1 * w2);
      for (const cd& x : p) {
        const cd pl = x * bw / 2.0;
        const cd r = std::sqrt(pl * pl - wo * wo);
        out.p.push_back(pl + r);
        out.p.push_back(pl - r);
      }
      out.z.assign(static_cast<std::size_t>(degree), cd(0.0, 0.0));
      out.k = std::pow(bw, degree);
      break;
    }
    case Band::stop: {
      const double bw = w2 - w1, wo = std::sqrt(w1 * w2);
      for (const cd& x : p) {
        const cd ph = (bw / 2.0) / x;
        const cd r = std::sqrt(ph * ph - wo * wo);
        out.p.push_back(ph + r);
        out.p.push_back(ph - r);
      }
      for (int i = 0; i < degree; ++i) {
        out.z.push_back(cd(0.0, wo));
        out.z.push_back(cd(0.0, -wo));
      }
      out.k = std::real(cd(1.0, 0.0) / prod_neg(prototype_poles(n)));
      break;
    }
  }
  return out;
}

Zpk bilinear(const Zpk& a, double fs) {
  const double fs2 = 2.0 * fs;
  Zpk d;
  cd num(1.0, 0.0), den(1.0, 0.0);
  for (const cd& z : a.z) {
    d.z.push_back((fs2 + z) / (fs2 - z));
    num *= fs2 - z;
  }
  for (const cd& p : a.p) {
    d.p.push_back((fs2 + p) / (fs2 - p));
    den *= fs2 - p;
  }
  while (d.z.size() < d.p.size()) d.z.push_back(cd(-1.0, 0.0));
  d.k = a.k * (num / den).real();
  return d;
}

Biquad section_from(cd p1, cd p2, bool two_poles, cd z1, cd z2, bool two_zeros) {
  Biquad s;
  s.b0 = 1.0;
  if (two_zeros) {
    s.b1 = -(z1 + z2).real();
    s.b2 = (z1 * z2).real();
  } else {
    s.b1 = -z1.real();
    s.b2 = 0.0;
  }
  if (two_poles) {
    s.a1 = -(p1 + p2).real();
    s.a2 = (p1 * p2).real();
  } else {
    s.a1 = -p1.real();
    s.a2 = 0.0;
  }
  return s;
}

cd section_response(const Biquad& s, cd zinv) {
  return (s.b0 + zinv * (s.b1 + zinv * s.b2)) / (1.0 + zinv * (s.a1 + zinv * s.a2));
}

// Pair poles and zeros into sections; poles farthest from the unit circle first.
std::vector<Biquad> zpk_to_sos(const Zpk& d, double ref_freq_norm /* rad/sample */) {
  constexpr double kTol = 1e-10;
  std::vector<cd> cpoles, rpoles, czeros, rzeros;
  for (const cd& p : d.p) {
    if (std::abs(p.imag()) <= kTol * std::max(1.0, std::abs(p))) rpoles.push_back(cd(p.real(), 0.0));
    else if (p.imag() > 0) cpoles.push_back(p);
  }
  for (const cd& z : d.z) {
    if (std::abs(z.imag()) <= kTol * std::max(1.0, std::abs(z))) rzeros.push_back(cd(z.real(), 0.0));
    else if (z.imag() > 0) czeros.push_back(z);
  }
  auto by_radius = [](const cd& a, const cd& b) { return std::abs(a) < std::abs(b); };
  std::sort(cpoles.begin(), cpoles.end(), by_radius);
  std::sort(rpoles.begin(), rpoles.end(), by_radius);
  std::sort(rzeros.begin(), rzeros.end(), [](const cd& a, const cd& b) { return a.real() < b.real(); });

  struct Sec {
    cd p1, p2;
    bool two;
  };
  std::vector<Sec> secs;
  // Real poles first (farther from the circle in practice), paired two by two.
  for (std::size_t i = 0; i + 1 < rpoles.size(); i += 2) secs.push_back({rpoles[i], rpoles[i + 1], true});
  const bool odd_real = rpoles.size() % 2 == 1;
  for (const cd& p : cpoles) secs.push_back({p, std::conj(p), true});
  if (odd_real) secs.insert(secs.begin(), Sec{rpoles.back(), cd(), false});

  std::vector<Biquad> sos;
  std::size_t zc = 0, zlo = 0, zhi = rzeros.size();
  for (const Sec& s : secs) {
    cd z1(-1.0, 0.0), z2(-1.0, 0.0);
    bool two_zeros = s.two;
    if (s.two) {
      if (zc < czeros.size()) {
        z1 = czeros[zc];
        z2 = std::conj(czeros[zc]);
        ++zc;
      } else if (zhi - zlo >= 2) {
        z1 = rzeros[zlo++];
        z2 = rzeros[--zhi];
      } else {
        throw std::logic_error("iir: zero/pole count mismatch in SOS pairing");
      }
    } else {
      if (zhi > zlo) z1 = rzeros[zlo++];
      else throw std::logic_error("iir: zero/pole count mismatch in SOS pairing");
    }
    sos.push_back(section_from(s.p1, s.p2, s.two, z1, z2, two_zeros));
  }
  // Gain: every section but the first has |H| = 1 at the reference frequency; the first carries the
  // rest so that the cascade gain equals k exactly.
  const cd zinv = std::exp(cd(0.0, -ref_freq_norm));
  double rest = 1.0;
  for (std::size_t i = 1; i < sos.size(); ++i) {
    const double g = std::abs(section_response(sos[i], zinv));
    const double sc = g > 0.0 ? 1.0 / g : 1.0;
    sos[i].b0 *= sc;
    sos[i].b1 *= sc;
    sos[i].b2 *= sc;
    rest *= sc;
  }
  const double k0 = d.k / rest;
  sos[0].b0 *= k0;
  sos[0].b1 *= k0;
  sos[0].b2 *= k0;
  return sos;
}

std::vector<Biquad> design(int order, Band band, double f1, double f2, double fs) {
  const double w1 = 2.0 * fs * std::tan(kPi * f1 / fs);
  const double w2 = band == Band::pass || band == Band::stop ? 2.0 * fs * std::tan(kPi * f2 / fs) : 0.0;
  const Zpk d = bilinear(analog_design(order, band, w1, w2), fs);
  double ref = 0.0;
  switch (band) {
    case Band::low: ref = 0.0; break;
    case Band::high: ref = kPi; break;
    case Band::pass: ref = 2.0 * std::atan(std::sqrt(w1 * w2) / (2.0 * fs)); break;
    case Band::stop: ref = 0.0; break;
  }
  return zpk_to_sos(d, ref);
}

}  // namespace

std::vector<Biquad> butter_lowpass(int order, double cutoff_hz, double fs) {
  check_common(order, fs, "butter_lowpass");
  check_edge(cutoff_hz, fs, "butter_lowpass", "cutoff_hz");
  return design(order, Band::low, cutoff_hz, 0.0, fs);
}

std::vector<Biquad> butter_highpass(int order, double cutoff_hz, double fs) {
  check_common(order, fs, "butter_highpass");
  check_edge(cutoff_hz, fs, "butter_highpass", "cutoff_hz");
  return design(order, Band::high, cutoff_hz, 0.0, fs);
}

static void check_band(int order, double lo, double hi, double fs, const char* what) {
  check_common(order, fs, what);
  check_edge(lo, fs, what, "low_hz");
  check_edge(hi, fs, what, "high_hz");
  if (!(lo < hi))
    throw std::invalid_argument(std::string(what) + ": low_hz (" + std::to_string(lo) +
                                ") must be below high_hz (" + std::to_string(hi) + ")");
}

std::vector<Biquad> butter_bandpass(int order, double lo, double hi, double fs) {
  check_band(order, lo, hi, fs, "butter_bandpass");
  return design(order, Band::pass, lo, hi, fs);
}

std::vector<Biquad> butter_bandstop(int order, double lo, double hi, double fs) {
  check_band(order, lo, hi, fs, "butter_bandstop");
  return design(order, Band::stop, lo, hi, fs);
}

std::complex<double> sos_response(std::span<const Biquad> sos, double freq_hz, double fs) {
  const cd zinv = std::exp(cd(0.0, -2.0 * kPi * freq_hz / fs));
  cd h(1.0, 0.0);
  for (const Biquad& s : sos) h *= section_response(s, zinv);
  return h;
}

// --- SosFilter ----------------------------------------------------------------------------------

SosFilter::SosFilter(std::vector<Biquad> sections)
    : sections_(std::move(sections)), state_(2 * sections_.size(), 0.0) {}

double SosFilter::process_double(double x) noexcept {
  double* st = state_.data();
  for (const Biquad& s : sections_) {
    const double y = s.b0 * x + st[0];
    st[0] = s.b1 * x - s.a1 * y + st[1];
    st[1] = s.b2 * x - s.a2 * y;
    x = y;
    st += 2;
  }
  return x;
}

float SosFilter::process(float x) noexcept { return static_cast<float>(process_double(x)); }

void SosFilter::process(const float* in, float* out, std::size_t n) noexcept {
  // Per-sample cascade keeps double precision between sections.
  for (std::size_t i = 0; i < n; ++i) out[i] = static_cast<float>(process_double(in[i]));
}

void SosFilter::reset() noexcept { std::fill(state_.begin(), state_.end(), 0.0); }

void SosFilter::set_steady_state(double x) noexcept {
  double scale = x;
  double* st = state_.data();
  for (const Biquad& s : sections_) {
    const double den = 1.0 + s.a1 + s.a2;
    const double g = den != 0.0 ? (s.b0 + s.b1 + s.b2) / den : 0.0;
    st[0] = scale * (g - s.b0);
    st[1] = scale * (s.b2 - s.a2 * g);
    scale *= g;
    st += 2;
  }
}

std::vector<float> filtfilt(std::span<const Biquad> sos, std::span<const float> x) {
  const std::size_t n = x.size();
  if (n == 0) return {};
  std::size_t first_order = 0, b2z = 0, a2z = 0;
  for (const Biquad& s : sos) {
    b2z += s.b2 == 0.0;
    a2z += s.a2 == 0.0;
  }
  first_order = std::min(b2z, a2z);
  std::size_t pad = 3 * (2 * sos.size() + 1 - first_order);
  pad = std::min(pad, n - 1);

  std::vector<double> ext(n + 2 * pad);
  for (std::size_t i = 0; i < pad; ++i) ext[i] = 2.0 * x[0] - x[pad - i];
  for (std::size_t i = 0; i < n; ++i) ext[pad + i] = x[i];
  for (std::size_t i = 0; i < pad; ++i) ext[pad + n + i] = 2.0 * x[n - 1] - x[n - 2 - i];

  SosFilter f(std::vector<Biquad>(sos.begin(), sos.end()));
  f.set_steady_state(ext.front());
  for (double& v : ext) v = f.process_double(v);
  f.set_steady_state(ext.back());
  for (std::size_t i = ext.size(); i-- > 0;) ext[i] = f.process_double(ext[i]);

  std::vector<float> y(n);
  for (std::size_t i = 0; i < n; ++i) y[i] = static_cast<float>(ext[pad + i]);
  return y;
}

}  // namespace locus::dsp
