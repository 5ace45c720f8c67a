// Prints filter designs and outputs for reference/check_filters.py (scipy comparison).
// Format, one record per line, whitespace separated:
//   X n x0 .. x{n-1}                          the common input signal
//   IIR kind order f1 f2 fs                   kind: lowpass highpass bandpass bandstop (f2 = 0 if unused)
//   SOS b0 b1 b2 a1 a2                        one line per section
//   Y n y..                                   SosFilter output for X
//   FF n y..                                  filtfilt output for X
//   FIR kind taps window beta f1 f2 fs        window: hamming blackman kaiser
//   H n h..                                   taps
//   G f power                                 goertzel_power of X at f (fs = 44100)
#include <cstdio>
#include <cmath>
#include <string>
#include <vector>

#include "locus/dsp/fir.hpp"
#include "locus/dsp/goertzel.hpp"
#include "locus/dsp/iir.hpp"

using namespace locus::dsp;

static void print_vec(const char* tag, const std::vector<float>& v) {
  std::printf("%s %zu", tag, v.size());
  for (float x : v) std::printf(" %.9g", x);
  std::printf("\n");
}

int main() {
  const std::size_t n = 3000;
  std::vector<float> x(n);
  std::uint32_t s = 12345;
  for (std::size_t i = 0; i < n; ++i) {
    s = s * 1664525u + 1013904223u;
    const double r = (static_cast<double>(s >> 8) / 16777216.0) - 0.5;
    x[i] = static_cast<float>(0.5 * std::sin(0.05 * i) + 0.3 * std::sin(2.6 * i) + r + (i > 100 ? 0.25 : 0.0));
  }
  print_vec("X", x);
  struct Case { std::string kind; int order; double f1, f2, fs; };
  const std::vector<Case> cases = {
      {"lowpass", 1, 1000, 0, 44100},   {"lowpass", 2, 5, 0, 100},       {"lowpass", 4, 3000, 0, 44100},
      {"lowpass", 7, 200, 0, 8000},     {"lowpass", 10, 15000, 0, 44100}, {"highpass", 1, 500, 0, 44100},
      {"highpass", 3, 17000, 0, 44100}, {"highpass", 6, 100, 0, 48000},  {"bandpass", 1, 1000, 2000, 44100},
      {"bandpass", 4, 17800, 20200, 44100}, {"bandpass", 5, 18500, 19500, 44100}, {"bandpass", 8, 300, 3400, 16000},
      {"bandpass", 3, 50, 20000, 44100}, {"bandstop", 2, 900, 1100, 8000}, {"bandstop", 5, 18000, 20000, 44100},
  };
  for (const Case& c : cases) {
    std::vector<Biquad> sos;
    if (c.kind == "lowpass") sos = butter_lowpass(c.order, c.f1, c.fs);
    else if (c.kind == "highpass") sos = butter_highpass(c.order, c.f1, c.fs);
    else if (c.kind == "bandpass") sos = butter_bandpass(c.order, c.f1, c.f2, c.fs);
    else sos = butter_bandstop(c.order, c.f1, c.f2, c.fs);
    std::printf("IIR %s %d %.17g %.17g %.17g\n", c.kind.c_str(), c.order, c.f1, c.f2, c.fs);
    for (const Biquad& b : sos) std::printf("SOS %.17g %.17g %.17g %.17g %.17g\n", b.b0, b.b1, b.b2, b.a1, b.a2);
    SosFilter f(sos);
    std::vector<float> y(n);
    f.process(x.data(), y.data(), n);
    print_vec("Y", y);
    print_vec("FF", filtfilt(sos, x));
  }
  struct FCase { std::string kind; std::size_t taps; FirWindow w; const char* wname; double beta, f1, f2, fs; };
  const std::vector<FCase> fcases = {
      {"lowpass", 63, FirWindow::hamming, "hamming", 0, 3000, 0, 44100},
      {"lowpass", 64, FirWindow::blackman, "blackman", 0, 1200, 0, 8000},
      {"lowpass", 101, FirWindow::kaiser, "kaiser", 8.6, 5000, 0, 44100},
      {"highpass", 51, FirWindow::hamming, "hamming", 0, 17000, 0, 44100},
      {"bandpass", 129, FirWindow::blackman, "blackman", 0, 18000, 20000, 44100},
      {"bandpass", 80, FirWindow::kaiser, "kaiser", 5.0, 300, 3400, 16000},
      {"bandstop", 91, FirWindow::hamming, "hamming", 0, 900, 1100, 8000},
  };
  for (const FCase& c : fcases) {
    FirWindowSpec w{c.w, c.beta};
    std::vector<double> h;
    if (c.kind == "lowpass") h = fir_lowpass(c.taps, c.f1, c.fs, w);
    else if (c.kind == "highpass") h = fir_highpass(c.taps, c.f1, c.fs, w);
    else if (c.kind == "bandpass") h = fir_bandpass(c.taps, c.f1, c.f2, c.fs, w);
    else h = fir_bandstop(c.taps, c.f1, c.f2, c.fs, w);
    std::printf("FIR %s %zu %s %.17g %.17g %.17g %.17g\n", c.kind.c_str(), c.taps, c.wname, c.beta, c.f1, c.f2, c.fs);
    std::printf("H %zu", h.size());
    for (double v : h) std::printf(" %.17g", v);
    std::printf("\n");
    FirFilter f(h);
    std::vector<float> y(n);
    f.process(x.data(), y.data(), n);
    print_vec("Y", y);
  }
  for (double f : {18000.0, 18250.0, 1000.0, 350.7, 21000.0}) std::printf("G %.17g %.17g\n", f, goertzel_power(x, f, 44100.0));
  return 0;
}
