// Camera geometry of a synthetic scene and the pixel rays through the plume.
//
// World frame: x to the right in the image, z up, y along the viewing
// direction away from the camera; the camera looks along +y and its optical
// axis meets the plane y = 0 at (center_x_m, 0, center_z_m), distance_m from
// the camera. Pixels: column i (x right), row r (y down), origin at the
// top-left pixel centre; the principal point is the image centre
// ((width-1)/2, (height-1)/2).
//
// Orthographic: pixel (i, r) is the ray parallel to +y through
//   x = center_x + (i - cx) * D * ifov,  z = center_z - (r - cy) * D * ifov.
// Perspective (pinhole, image plane perpendicular to y): the ray from the
// camera centre C = (center_x, -D, center_z) along
//   d = ((i - cx) ifov, 1, -(r - cy) ifov),
// so on any plane y the pixels form a regular grid of spacing ifov (y + D).
#pragma once

#include <string>

namespace qogi::synth {

enum class Projection { kOrthographic, kPerspective };

Projection ParseProjection(const std::string& text);
std::string ProjectionName(Projection p);

struct View {
  // Image width and height [pixels], each in [1, 8192]. Default 320 x 256.
  int width_px = 320;
  int height_px = 256;
  // One pixel's angular size [rad], in (0, 0.1]. Default 24 deg / 320.
  double ifov_rad = 24.0 / 320.0 * 3.14159265358979323846 / 180.0;
  // Distance from the camera to the plane y = 0 (the plume axis) [m], in
  // [0.05, 1e4]. Default 1.5.
  double distance_m = 1.5;
  // Parallel rays (pixel footprint D * ifov everywhere) or true perspective.
  // Default orthographic.
  Projection projection = Projection::kOrthographic;
  // Where the optical axis meets the plane y = 0 [m]. Default (0, 0).
  double center_x_m = 0.0;
  double center_z_m = 0.0;

  void Check() const;

  double cx() const { return 0.5 * (width_px - 1); }
  double cy() const { return 0.5 * (height_px - 1); }
  // Pixel footprint on the plane y = 0 [m].
  double footprint_m() const { return distance_m * ifov_rad; }
  // Pixel spacing on the plane at depth y [m].
  double Scale(double y) const {
    return projection == Projection::kOrthographic ? footprint_m() : ifov_rad * (y + distance_m);
  }
  // World x and z of the pixel ray (column, row may be fractional) at depth y.
  double PixelX(double column, double y) const { return center_x_m + (column - cx()) * Scale(y); }
  double PixelZ(double row, double y) const { return center_z_m - (row - cy()) * Scale(y); }
  // Column and row of the ray through world point (x, y, z).
  double Column(double x, double y) const { return cx() + (x - center_x_m) / Scale(y); }
  double Row(double z, double y) const { return cy() - (z - center_z_m) / Scale(y); }
  // Path length along the pixel's ray per unit depth y (1 for orthographic).
  double PathPerDepth(int column, int row) const;
  // Unit direction of the pixel's ray and a point on it.
  void Ray(int column, int row, double origin[3], double direction[3]) const;
};

}  // namespace qogi::synth
