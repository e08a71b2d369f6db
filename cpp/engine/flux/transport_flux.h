// The time-averaged flux level of a plume along an image axis from the
// transport of its line-integrated column (the time of flight of its
// structures), and the typical displacement of those structures.
//
// Frames are (T, H, W) row-major float stacks proportional to column density
// (zero without gas), in any linear unit. Per line across the axis (rows for
// kUp/kDown, columns for kLeft/kRight) the continuity equation becomes
// one-dimensional and exact: with C_t(y) the column summed over the lines
// beyond level y (towards the axis), C_t(k + d_k) = C_{t+1}(k) + O_t, with
// d_k a steady displacement per level and O_t what left the frame in pair t.
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "engine/util/parallel.h"

namespace qogi {

// The direction the plume moves in the image (away from its source).
enum class FluxAxis { kUp, kDown, kLeft, kRight };

// "up", "down", "left", "right" <-> FluxAxis; throws std::invalid_argument
// naming the accepted values.
FluxAxis ParseFluxAxis(const std::string& name);
const char* FluxAxisName(FluxAxis axis);
// True for kUp/kDown (lines are rows).
inline bool AlongRows(FluxAxis axis) { return axis == FluxAxis::kUp || axis == FluxAxis::kDown; }

struct TransportFluxOptions {
  // Direction of the plume's transport in the image.
  FluxAxis axis = FluxAxis::kUp;
  // Row (kUp, kDown) or column of the source's exit in the frames (rounded
  // half to even): the lines beyond it are the source. NaN (default): the
  // gas enters across the near edge of the frame.
  double source_index = std::numeric_limits<double>::quiet_NaN();
  // Interval between consecutive frames in nominal frame intervals (T - 1
  // values > 0, e.g. 2 where a frame was dropped); empty (default): all 1.
  // Displacements, velocities and fluxes are then per nominal interval.
  std::vector<double> intervals;
  // Frame pairs per time-of-flight fit (default 0: one fit over the whole
  // record; else >= 4). The record's pairs are split into round(pairs /
  // window) windows of nearly equal length, each with its own steady
  // displacements, and the flux is the mass crossing each level summed over
  // the windows per nominal interval: the displacement follows the gas's
  // speed as it changes over the record (a draft of a few seconds' time scale
  // in a lab; a column piles up where the gas slows, and one steady
  // displacement over 10 s read the GF320 lab release's exact columns
  // 0.74-1.02 of the truth, 0.85 on average). Each window's fit starts from
  // the whole record's. Shorter windows read high (their fits follow the
  // puffs' own speeds).
  int window = 0;
  // Gauss-Newton iterations at most (default 100; stops at steps < 1e-4 px).
  int iterations = 100;
  // Lines averaged either side of a level in the coarse correlation search
  // (default 8).
  int half_window = 8;
  // Worker threads (0 = all cores).
  int num_threads = 0;
  // The pixels summed across each line (H x W, row-major, nonzero = summed),
  // e.g. the plume's band: the same as giving the frames multiplied by it,
  // without that second stack. Empty (default): every pixel.
  std::vector<std::uint8_t> mask;

  // Throws std::invalid_argument for a bad field or one that does not fit
  // frames of (T, H, W).
  void Check(std::size_t T, std::size_t H, std::size_t W) const;
};

// Per line of the frames (not turned: index = row or column).
struct TransportFluxResult {
  // Time-averaged flux through each line towards the axis [frame unit x
  // px/frame] (sum over the line of frame x velocity); NaN in the source and
  // beyond the last line with gas. For kg/s with columns in kg/m2, multiply
  // by the pixel size [m] squared and the frame rate [1/s].
  std::vector<double> flux;
  // Time-averaged sum of the frames over each line [frame unit].
  std::vector<double> line_column;
  // flux / line_column: time-averaged mass-weighted velocity [px/frame].
  std::vector<double> velocity;
  // Steady displacement of each line's level over one frame [px/frame]; NaN
  // where not solved.
  std::vector<double> displacement;
  // How little of each solved level's column the time of flight explains:
  // over the pairs, the residual of C_t(k + d_k) = C_{t+1}(k) + O_t (after
  // the outflows) squared, over the squared anomaly of C_{t+1}(k) about its
  // mean (summed over the windows). 0: the structures are carried exactly;
  // about 1 or more: the displacement explains no more than the column's own
  // mean (structures that change beyond recognition between frames, or move
  // further than the fit can follow). NaN where not solved.
  std::vector<double> unexplained;
  FluxAxis axis = FluxAxis::kUp;
};

// Sums of the frames across each line, turned so that line 0 is the far end
// along the axis: (T, n) row-major, n = H (kUp/kDown) or W; only the pixels
// where `mask` (H x W, or null: all) is nonzero.
std::vector<double> LineSums(const float* frames, std::size_t T, std::size_t H, std::size_t W,
                             FluxAxis axis, int num_threads = 0,
                             const RunControl* control = nullptr,
                             const std::uint8_t* mask = nullptr);

// The transport flux of T >= 3 finite frames. Throws std::invalid_argument
// for bad input and for frames that do not change over time (a steady plume
// does not fix its flux level); qogi::Cancelled when `control` asks.
TransportFluxResult TransportFlux(const float* frames, std::size_t T, std::size_t H, std::size_t W,
                                  const TransportFluxOptions& options = {},
                                  const RunControl* control = nullptr);

// Typical displacement [px/frame] of the structures along `axis`: where the
// correlation of consecutive frames' line sums (their temporal anomalies,
// over all lines) peaks among shifts 0 ... max_px, sub-pixel by a parabola
// through the peak. NaN when the peak is at max_px or the frames do not
// change. T >= 3, max_px >= 2.
double TypicalDisplacement(const float* frames, std::size_t T, std::size_t H, std::size_t W,
                           FluxAxis axis = FluxAxis::kUp, int max_px = 16, int num_threads = 0);

}  // namespace qogi
