// Bindings of engine/background: the drift's measurement and the two-layer
// (static + drifting) background, with their options structs (same field
// names as in C++). Glue only.
#include "common.h"

#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "engine/background/drifting.h"
#include "engine/background/held_pixels.h"
#include "engine/background/temporal_stats.h"

namespace qogi {
namespace {

// Views of the images of a (T, H, W) float32 stack (no copies).
std::vector<cv::Mat> StackViews(const FloatArray& frames) {
  CheckNdim(frames, 3, "frames");
  const int t = static_cast<int>(frames.shape(0)), h = static_cast<int>(frames.shape(1)),
            w = static_cast<int>(frames.shape(2));
  Require(t > 0 && h > 1 && w > 1,
          "frames must be (T, H, W) with T >= 1, H, W >= 2; got shape " + ShapeOf(frames));
  std::vector<cv::Mat> out;
  for (int i = 0; i < t; ++i)
    out.emplace_back(h, w, CV_32FC1, const_cast<float*>(frames.data()) + std::size_t(i) * h * w);
  return out;
}

using MaskArray = py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast>;
using ImageArray = py::array_t<float, py::array::c_style | py::array::forcecast>;

// A (H, W) view of a mask or an image (no copy).
cv::Mat MaskView(const MaskArray& a, const char* name) {
  CheckNdim(a, 2, name);
  Require(a.shape(0) > 0 && a.shape(1) > 0, std::string(name) + " is empty");
  return cv::Mat(static_cast<int>(a.shape(0)), static_cast<int>(a.shape(1)), CV_8UC1,
                 const_cast<std::uint8_t*>(a.data()));
}

cv::Mat ImageView(const ImageArray& a, const char* name) {
  CheckNdim(a, 2, name);
  Require(a.shape(0) > 0 && a.shape(1) > 0, std::string(name) + " is empty");
  return cv::Mat(static_cast<int>(a.shape(0)), static_cast<int>(a.shape(1)), CV_32FC1,
                 const_cast<float*>(a.data()));
}

template <typename T>
py::array_t<T> Copy(const cv::Mat& m) {
  py::array_t<T> out({m.rows, m.cols});
  for (int y = 0; y < m.rows; ++y)
    std::memcpy(out.mutable_data(y, 0), m.ptr<T>(y), sizeof(T) * std::size_t(m.cols));
  return out;
}

// A (T, ...) stack as T frames of `values` contiguous values, frame t at
// data + t * stride: a C-contiguous array or a slice of one along its first
// axis (f[:, c] of a (T, C, h, w) stack); other layouts are copied.
template <typename T>
struct Stack {
  py::array_t<T> keep;  // the array read (a copy only for other layouts)
  const T* data = nullptr;
  std::size_t frames = 0, stride = 0, values = 1;
  std::vector<py::ssize_t> trailing;
};

template <typename T>
Stack<T> AsStack(const py::array& a) {
  Require(a.ndim() >= 1, "frames must have a first (time) axis; got a scalar");
  auto arr = py::array_t<T>::ensure(a);
  Require(static_cast<bool>(arr), "frames must be numbers");
  bool trailing_c = true;
  py::ssize_t expect = static_cast<py::ssize_t>(sizeof(T));
  for (py::ssize_t i = arr.ndim() - 1; i >= 1; --i) {
    if (arr.shape(i) > 1 && arr.strides(i) != expect) trailing_c = false;
    expect *= arr.shape(i);
  }
  const bool frame_ok =
      arr.shape(0) <= 1 ||
      (arr.strides(0) > 0 && arr.strides(0) % sizeof(T) == 0 && arr.strides(0) >= expect);
  if (!trailing_c || !frame_ok)
    arr = py::array_t<T, py::array::c_style | py::array::forcecast>(arr);
  Stack<T> s;
  s.keep = arr;
  s.data = arr.data();
  s.frames = static_cast<std::size_t>(arr.shape(0));
  for (py::ssize_t i = 1; i < arr.ndim(); ++i) {
    s.values *= static_cast<std::size_t>(arr.shape(i));
    s.trailing.push_back(arr.shape(i));
  }
  s.stride = s.frames > 1 ? static_cast<std::size_t>(arr.strides(0)) / sizeof(T) : s.values;
  return s;
}

template <typename T>
py::array Percentiles(const py::array& frames, const std::vector<double>& q, int num_threads) {
  const Stack<T> s = AsStack<T>(frames);
  std::vector<py::ssize_t> shape{static_cast<py::ssize_t>(q.size())};
  shape.insert(shape.end(), s.trailing.begin(), s.trailing.end());
  py::array_t<double> out(shape);
  double* o = out.mutable_data();
  {
    py::gil_scoped_release release;
    TemporalPercentiles<T>(s.data, s.frames, s.stride, s.values, q, o, num_threads);
  }
  return out;
}

template <typename T>
py::array Spread(const py::array& frames, int num_threads) {
  const Stack<T> s = AsStack<T>(frames);
  py::array_t<T> out(s.trailing);
  T* o = out.mutable_data();
  {
    py::gil_scoped_release release;
    DifferenceSpread<T>(s.data, s.frames, s.stride, s.values, o, num_threads);
  }
  return out;
}

void BindTemporalStats(py::module_& m) {
  m.def(
      "temporal_percentiles",
      [](const py::array& frames, const std::vector<double>& q, int num_threads) {
        if (py::isinstance<py::array_t<float>>(frames))
          return Percentiles<float>(frames, q, num_threads);
        return Percentiles<double>(frames, q, num_threads);
      },
      py::arg("frames"), py::arg("q"), py::arg("num_threads") = 1,
      "np.percentile(frames, q, axis=0) of a (T, ...) float32 or float64 stack, the same values "
      "(numpy's linear method): (len(q), ...) float64 (engine/background/temporal_stats.h). "
      "num_threads 0: all cores.");
  m.def(
      "difference_spread",
      [](const py::array& frames, int num_threads) {
        if (py::isinstance<py::array_t<float>>(frames)) return Spread<float>(frames, num_threads);
        return Spread<double>(frames, num_threads);
      },
      py::arg("frames"), py::arg("num_threads") = 1,
      "np.median(|d - np.median(d, 0)|, 0) of d = np.diff(frames, axis=0), a (T >= 2, ...) "
      "float32 or float64 stack, the same values: (...) in the frames' type.");
}

void BindHeldPixels(py::module_& m) {
  m.def(
      "connected_components8",
      [](const MaskArray& mask) {
        const cv::Mat view = MaskView(mask, "mask");
        cv::Mat labels;
        ConnectedComponents8(view, &labels);
        return Copy<std::int32_t>(labels);
      },
      py::arg("mask"),
      "8-connected components of the nonzero pixels of mask ((H, W) uint8): labels (H, W) "
      "int32, 0 outside (engine/background/held_pixels.h).");
  m.def(
      "dilate_disk",
      [](const MaskArray& mask, int radius) {
        const cv::Mat view = MaskView(mask, "mask");
        cv::Mat out;
        DilateDisk(view, radius, &out);
        return Copy<std::uint8_t>(out);
      },
      py::arg("mask"), py::arg("radius"),
      "mask ((H, W) uint8, nonzero inside) dilated by a disk of radius px: (H, W) uint8, 1 "
      "inside.");
  m.def(
      "open_disk",
      [](const MaskArray& mask, int radius) {
        const cv::Mat view = MaskView(mask, "mask");
        cv::Mat out;
        OpenDisk(view, radius, &out);
        return Copy<std::uint8_t>(out);
      },
      py::arg("mask"), py::arg("radius"),
      "mask ((H, W) uint8) opened by a disk of radius px (parts narrower than it removed): "
      "(H, W) uint8, 1 inside.");
  m.def(
      "resize_image",
      [](const ImageArray& image, int width, int height, const std::string& mode) {
        Require(mode == "area" || mode == "linear",
                "mode must be 'area' or 'linear'; got '" + mode + "'");
        const cv::Mat view = ImageView(image, "image");
        cv::Mat out;
        ResizeImage(view, width, height, mode == "area" ? ResizeMode::kArea : ResizeMode::kLinear,
                    &out);
        return Copy<float>(out);
      },
      py::arg("image"), py::arg("width"), py::arg("height"), py::arg("mode"),
      "image ((H, W) float32) resized to (height, width): 'area' averages (shrinking), "
      "'linear' interpolates bilinearly.");
  m.def(
      "inpaint_ns",
      [](const ImageArray& image, const MaskArray& mask, double radius_px) {
        const cv::Mat img = ImageView(image, "image"), msk = MaskView(mask, "mask");
        cv::Mat out;
        {
          py::gil_scoped_release release;
          InpaintNavierStokes(img, msk, radius_px, &out);
        }
        return Copy<float>(out);
      },
      py::arg("image"), py::arg("mask"), py::arg("radius_px"),
      "image ((H, W) float32) with the nonzero pixels of mask ((H, W) uint8) filled by "
      "Navier-Stokes inpainting from radius_px around; values of order one and more.");
}

}  // namespace

void BindBackground(py::module_& m) {
  BindHeldPixels(m);
  BindTemporalStats(m);
  BindOptions<DriftOptions>(
      m, "DriftOptions", "Options of the drift measurement (engine/background/drifting.h).",
      Args::kKeywordOnly,
      Field("difference_lag", &DriftOptions::difference_lag,
            "frames between the two frames of each difference image, >= 1 (default 5)"),
      Field("short_lag", &DriftOptions::short_lag,
            "frames between the difference images registered from rest, >= 1 (default 2)"),
      Field("long_lag", &DriftOptions::long_lag,
            "frames between the difference images registered warm-started, >= short_lag "
            "(default 15)"),
      Field("max_pairs", &DriftOptions::max_pairs,
            "registrations at most per lag, >= 1 (default 15)"),
      Field("smoothing_px", &DriftOptions::smoothing_px,
            "Gaussian smoothing before registration [px sigma], 0-20 (default 1)"));
  BindOptions<DriftingBackgroundOptions>(
      m, "DriftingBackgroundOptions",
      "Options of the two-layer drifting background (engine/background/drifting.h).",
      Args::kKeywordOnly,
      Field("percentile", &DriftingBackgroundOptions::percentile,
            "percentile on the gas's low side [%], in (0, 50) (default 5)"),
      Field("window_s", &DriftingBackgroundOptions::window_s,
            "length of the drifting layer's running window [s], > 0 (default 10)"),
      Field("iterations", &DriftingBackgroundOptions::iterations,
            "alternations between the static and the drifting layer, 1-20 (default 3)"),
      Field("num_threads", &DriftingBackgroundOptions::num_threads,
            "worker threads, >= 0 (default 0: all)"));

  m.def(
      "measure_drift",
      [](const FloatArray& frames, const DoubleArray& times_s, const DriftOptions& options) {
        const std::vector<cv::Mat> f = StackViews(frames);
        const std::vector<double> t = ToVector(times_s, "times_s");
        DriftResult r;
        {
          py::gil_scoped_release release;
          r = MeasureDrift(f, t, options);
        }
        using R = DriftResult;
        return ToDict(r, Field("vx_px_s", &R::vx_px_s), Field("vy_px_s", &R::vy_px_s),
                      Field("spread_vx_px_s", &R::spread_vx_px_s),
                      Field("spread_vy_px_s", &R::spread_vy_px_s), Field("pairs", &R::pairs),
                      Field("converged", &R::converged),
                      Field("inlier_fraction", &R::inlier_fraction),
                      Field("measured", &R::measured));
      },
      py::arg("frames"), py::arg("times_s"), py::arg("options") = DriftOptions{},
      "The drift velocity of the background of frames ((T, H, W) float32, one channel, "
      "evenly spaced) at times_s [s] (T,): registration of difference images, which hold no "
      "static background. dict vx_px_s, vy_px_s [px/s] (x right, y down), spread_vx_px_s, "
      "spread_vy_px_s (the pairs' spread), pairs, converged, inlier_fraction, measured "
      "(False: fewer than half the pairs converged; the velocity is then 0).");

  py::class_<DriftingBackground>(
      m, "DriftingBackground",
      "The background of a scene whose background drifts: a static layer S and a layer M "
      "carried at (vx, vy) px/s, background(x, t) = S(x) + M_t(x - v t), each a sign-aware "
      "low percentile (M over a running window in its own frame).")
      .def(py::init([](const FloatArray& frames, const DoubleArray& times_s, double vx, double vy,
                       double sign, const DriftingBackgroundOptions& options) {
             const std::vector<cv::Mat> f = StackViews(frames);
             const std::vector<double> t = ToVector(times_s, "times_s");
             py::gil_scoped_release release;
             return DriftingBackground(f, t, vx, vy, sign, options);  // copies what it keeps
           }),
           py::arg("frames"), py::arg("times_s"), py::arg("vx_px_s"), py::arg("vy_px_s"),
           py::arg("sign"), py::arg("options") = DriftingBackgroundOptions{})
      .def(
          "at",
          [](const DriftingBackground& self, double time_s) {
            cv::Mat b;
            {
              py::gil_scoped_release release;
              self.At(time_s, &b);
            }
            py::array_t<float> out({b.rows, b.cols});
            std::memcpy(out.mutable_data(), b.ptr<float>(), sizeof(float) * b.total());
            return out;
          },
          py::arg("time_s"), "The background at time_s [s]: (H, W) float32.")
      .def_property_readonly(
          "static_layer",
          [](const DriftingBackground& self) {
            const cv::Mat& s = self.static_layer();
            py::array_t<float> out({s.rows, s.cols});
            std::memcpy(out.mutable_data(), s.ptr<float>(), sizeof(float) * s.total());
            return out;
          },
          "The static layer S: (H, W) float32.")
      .def_property_readonly("knots", &DriftingBackground::knots,
                             "The number of knots of the drifting layer.");
}

}  // namespace qogi
