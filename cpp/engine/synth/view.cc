#include "engine/synth/view.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <stdexcept>

#include "engine/util/check.h"

namespace qogi::synth {

Projection ParseProjection(const std::string& text) {
  std::string t;
  for (char c : text) t += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (t == "orthographic") return Projection::kOrthographic;
  if (t == "perspective") return Projection::kPerspective;
  throw std::invalid_argument("projection must be \"orthographic\" or \"perspective\"; got \"" +
                              text + "\"");
}

std::string ProjectionName(Projection p) {
  return p == Projection::kOrthographic ? "orthographic" : "perspective";
}

void View::Check() const {
  CheckInRange(width_px, 1, 8192, "width_px", "pixels");
  CheckInRange(height_px, 1, 8192, "height_px", "pixels");
  if (!(std::isfinite(ifov_rad) && ifov_rad > 0 && ifov_rad <= 0.1))
    throw std::invalid_argument("ifov_rad must be within (0, 0.1] rad; got " +
                                FormatNumber(ifov_rad));
  CheckInRange(distance_m, 0.05, 1e4, "distance_m", "m");
  CheckInRange(center_x_m, -1e4, 1e4, "center_x_m", "m");
  CheckInRange(center_z_m, -1e4, 1e4, "center_z_m", "m");
  if (projection == Projection::kPerspective) {
    const double half = 0.5 * std::max(width_px, height_px) * ifov_rad;
    if (!(half < 1.2))
      throw std::invalid_argument(
          "the perspective field of view is too wide (half-angle "
          "tangent " +
          FormatNumber(half) + " must be < 1.2); reduce ifov_rad or the image size");
  }
}

double View::PathPerDepth(int column, int row) const {
  if (projection == Projection::kOrthographic) return 1.0;
  const double a = (column - cx()) * ifov_rad, b = (row - cy()) * ifov_rad;
  return std::sqrt(1 + a * a + b * b);
}

void View::Ray(int column, int row, double origin[3], double direction[3]) const {
  if (projection == Projection::kOrthographic) {
    origin[0] = PixelX(column, 0);
    origin[1] = -distance_m;
    origin[2] = PixelZ(row, 0);
    direction[0] = 0;
    direction[1] = 1;
    direction[2] = 0;
    return;
  }
  origin[0] = center_x_m;
  origin[1] = -distance_m;
  origin[2] = center_z_m;
  const double a = (column - cx()) * ifov_rad, b = -(row - cy()) * ifov_rad;
  const double norm = std::sqrt(1 + a * a + b * b);
  direction[0] = a / norm;
  direction[1] = 1 / norm;
  direction[2] = b / norm;
}

}  // namespace qogi::synth
