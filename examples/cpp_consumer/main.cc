// Computes the band radiance of a blackbody through a 3.2-3.4 um channel with
// the installed qogi engine, and back to temperature.
#include <engine/qogi.h>

#include <cmath>
#include <cstdio>

int main() {
  const qogi::SpectralResponse channel({2941.18, 3125.0}, {1.0, 1.0},
                                       "3.2-3.4 um bandpass");
  const double t = 300.0;
  const double l = channel.BandRadiance(t);
  const double back = channel.RadiometricTemperature(l);
  std::printf("qogi consumer: %s, T = %.2f K -> L = %.6f W/(m2 sr) -> T = %.6f K\n",
              channel.name().c_str(), t, l, back);
  return std::abs(back - t) < 1e-6 ? 0 : 1;
}
