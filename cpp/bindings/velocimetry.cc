// Bindings of engine/velocimetry: the option structs (same field names as in
// C++), a flow estimator per method, post-processing and units. Glue only.
#include "common.h"

#include <opencv2/core.hpp>
#include <opencv2/core/utility.hpp>

#include <algorithm>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "engine/velocimetry/flow.h"
#include "engine/velocimetry/fluid_flow.h"
#include "engine/velocimetry/horn_schunck.h"
#include "engine/velocimetry/lucas_kanade.h"
#include "engine/velocimetry/opencv_flow.h"
#include "engine/velocimetry/piv.h"
#include "engine/velocimetry/postprocess.h"

namespace qogi {
namespace {

using ByteArray = py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast>;
// An 8-bit array written in place (bound with noconvert: never a copy).
using OutByteArray = py::array_t<std::uint8_t, py::array::c_style>;

cv::Mat FloatMat(const FloatArray& a, const char* name) {
  CheckNdim(a, 2, name);
  return cv::Mat(static_cast<int>(a.shape(0)), static_cast<int>(a.shape(1)), CV_32FC1,
                 const_cast<float*>(a.data()));
}

cv::Mat ByteMat(const ByteArray& a, const char* name) {
  CheckNdim(a, 2, name);
  return cv::Mat(static_cast<int>(a.shape(0)), static_cast<int>(a.shape(1)), CV_8UC1,
                 const_cast<std::uint8_t*>(a.data()));
}

template <typename Scalar>
py::array_t<Scalar> MatToArray(const cv::Mat& m) {
  py::array_t<Scalar> out({m.rows, m.cols});
  cv::Mat dst(m.rows, m.cols, m.type(), out.mutable_data());
  m.copyTo(dst);
  return out;
}

// A flow method and its reusable buffers.
class FlowEstimator {
 public:
  explicit FlowEstimator(const py::object& options) {
    if (py::isinstance<FluidFlowOptions>(options))
      impl_ = std::make_unique<FluidFlow>(options.cast<FluidFlowOptions>());
    else if (py::isinstance<HornSchunckOptions>(options))
      impl_ = std::make_unique<HornSchunckFlow>(options.cast<HornSchunckOptions>());
    else if (py::isinstance<LucasKanadeOptions>(options))
      impl_ = std::make_unique<LucasKanadeFlow>(options.cast<LucasKanadeOptions>());
    else if (py::isinstance<FarnebackOptions>(options))
      impl_ = std::make_unique<FarnebackFlow>(options.cast<FarnebackOptions>());
    else if (py::isinstance<DisOptions>(options))
      impl_ = std::make_unique<DisFlow>(options.cast<DisOptions>());
    else if (py::isinstance<PivOptions>(options))
      impl_ = std::make_unique<PivFlow>(options.cast<PivOptions>());
    else
      throw py::type_error(
          "options must be one of FluidFlowOptions, HornSchunckOptions, "
          "LucasKanadeOptions, FarnebackOptions, DisOptions, PivOptions; got " +
          std::string(py::str(py::type::of(options).attr("__name__"))));
  }

  std::string method() const { return FlowMethodName(impl_->method()); }

  void SetSourceMask(const py::object& source) {
    auto* fluid = dynamic_cast<FluidFlow*>(impl_.get());
    if (!fluid)
      throw std::invalid_argument("source_mask applies to the fluid method only; this is " +
                                  method());
    if (source.is_none()) {
      fluid->set_source_mask(cv::Mat());
      return;
    }
    const ByteArray a = source.cast<ByteArray>();
    fluid->set_source_mask(ByteMat(a, "source_mask"));
  }

  py::tuple Calc(const FloatArray& prev, const FloatArray& next, const py::object& mask,
                 const py::object& u0, const py::object& v0) {
    const cv::Mat p = FloatMat(prev, "prev"), n = FloatMat(next, "next");
    ByteArray mask_array;
    const cv::Mat m = OptionalMask(mask, &mask_array);
    FlowField& f = field_;
    if (!u0.is_none() && !v0.is_none()) {
      const FloatArray ua = u0.cast<FloatArray>(), va = v0.cast<FloatArray>();
      FloatMat(ua, "flow u").copyTo(f.u);
      FloatMat(va, "flow v").copyTo(f.v);
      Require(f.u.size() == p.size() && f.v.size() == p.size(),
              "the warm-start flow must have the frames' shape");
    } else {
      f.u.release();
      f.v.release();
    }
    {
      py::gil_scoped_release release;
      impl_->Calc(p, n, f, m);
    }
    const cv::Mat valid01 = (f.valid != 0) / 255;
    return py::make_tuple(MatToArray<float>(f.u), MatToArray<float>(f.v),
                          MatToArray<float>(f.quality), MatToArray<std::uint8_t>(valid01),
                          f.residual_ratio);
  }

  // Calc for a sequence: warm-started (warm = true) from this estimator's
  // own previous result, which it keeps, and written into the caller's
  // arrays (u, v, quality: float32 (H, W); valid: uint8 (H, W), 0/1): no
  // copies of the warm start or of the results through new arrays. Returns
  // the residual ratio.
  double CalcInto(const FloatArray& prev, const FloatArray& next, const py::object& mask, bool warm,
                  FloatArray u, FloatArray v, FloatArray quality, OutByteArray valid) {
    const cv::Mat p = FloatMat(prev, "prev"), n = FloatMat(next, "next");
    ByteArray mask_array;
    const cv::Mat m = OptionalMask(mask, &mask_array);
    const cv::Mat du = FloatMat(u, "u"), dv = FloatMat(v, "v"), dq = FloatMat(quality, "quality");
    CheckNdim(valid, 2, "valid");
    const cv::Mat dk(static_cast<int>(valid.shape(0)), static_cast<int>(valid.shape(1)), CV_8UC1,
                     valid.mutable_data());
    for (const cv::Mat* out : {&du, &dv, &dq, &dk})
      Require(out->size() == p.size(), "the output arrays must have the frames' shape " +
                                           ShapeOf(prev) + "; got " + std::to_string(out->rows) +
                                           " x " + std::to_string(out->cols));
    FlowField& f = field_;
    Require(!warm || f.HasSize(p.size()),
            "warm=True needs a previous call with frames of the same shape " + ShapeOf(prev));
    if (!warm) {
      f.u.release();
      f.v.release();
    }
    {
      py::gil_scoped_release release;
      impl_->Calc(p, n, f, m);
      f.u.copyTo(du);
      f.v.copyTo(dv);
      f.quality.copyTo(dq);
      cv::min(f.valid, 1, dk);  // the engine's 0 / nonzero as 0 / 1
    }
    return f.residual_ratio;
  }

 private:
  // The gas mask argument: empty for None, else a view of `keep` (which holds
  // the converted array).
  static cv::Mat OptionalMask(const py::object& mask, ByteArray* keep) {
    if (mask.is_none()) return cv::Mat();
    *keep = mask.cast<ByteArray>();
    return ByteMat(*keep, "mask");
  }

  std::unique_ptr<OpticalFlow> impl_;
  FlowField field_;
};

std::vector<cv::Mat> Slices(const py::array& a, int type) {
  std::vector<cv::Mat> out;
  const int T = static_cast<int>(a.shape(0)), H = static_cast<int>(a.shape(1)),
            W = static_cast<int>(a.shape(2));
  const std::size_t bytes = CV_ELEM_SIZE(type) * static_cast<std::size_t>(H) * W;
  auto* base = static_cast<std::uint8_t*>(const_cast<void*>(a.data()));
  for (int t = 0; t < T; ++t) out.emplace_back(H, W, type, base + t * bytes);
  return out;
}

}  // namespace

void BindVelocimetry(py::module_& m) {
  BindOptions<FluidFlowOptions>(
      m, "FluidFlowOptions",
      "Options of the continuity-equation (fluid) flow; "
      "see qogi.velocimetry.",
      Args::kKeywordOnly,
      Field("alpha", &FluidFlowOptions::alpha, "smoothness weight, > 0 (default 0.1)"),
      Field("alpha_div", &FluidFlowOptions::alpha_div,
            "weight of short-scale divergence, >= 0 (default 3)"),
      Field("alpha_curl", &FluidFlowOptions::alpha_curl,
            "weight of short-scale vorticity, >= 0 (default 0)"),
      Field("div_curl_scale", &FluidFlowOptions::div_curl_scale,
            "scale [px] below which div/curl are penalised, > 0 (default 8)"),
      Field("smoothness_scale", &FluidFlowOptions::smoothness_scale,
            "scale [px] above which the flow is not smoothed, >= 0, 0 = classic "
            "smoothness (default 8)"),
      Field("patch_search_scale", &FluidFlowOptions::patch_search_scale,
            "finest scale of the patch-search initialisation, 0 = full resolution, "
            "-1 = none (default 0)"),
      Field("patch_size", &FluidFlowOptions::patch_size,
            "patch side of the search [px], 4-64 (default 8)"),
      Field("patch_stride", &FluidFlowOptions::patch_stride,
            "patch spacing of the search [px], < patch_size (default 4)"),
      Field("patch_iterations", &FluidFlowOptions::patch_iterations,
            "gradient-descent iterations per patch (default 16)"),
      Field("patch_search_warm", &FluidFlowOptions::patch_search_warm,
            "run the search also when warm-started (default False)"),
      Field("levels", &FluidFlowOptions::levels, "pyramid levels, 1-12 (default 5)"),
      Field("min_level_size", &FluidFlowOptions::min_level_size,
            "smallest side of the coarsest level [px] (default 16)"),
      Field("finest_level", &FluidFlowOptions::finest_level,
            "finest level solved, 0 = full resolution (default 1)"),
      Field("warm_levels", &FluidFlowOptions::warm_levels,
            "levels solved after the search or a warm start, 0 = all (default 3)"),
      Field("warps", &FluidFlowOptions::warps, "warps per level (default 2)"),
      Field("iterations", &FluidFlowOptions::iterations,
            "conjugate-gradient iterations per warp (default 10)"),
      Field("tolerance", &FluidFlowOptions::tolerance, "relative CG tolerance (default 1e-3)"));
  BindOptions<HornSchunckOptions>(
      m, "HornSchunckOptions", "Options of coarse-to-fine Horn-Schunck.", Args::kKeywordOnly,
      Field("alpha", &HornSchunckOptions::alpha, "smoothness weight, > 0 (default 0.3)"),
      Field("levels", &HornSchunckOptions::levels, "pyramid levels (default 5)"),
      Field("min_level_size", &HornSchunckOptions::min_level_size,
            "smallest side of the coarsest level [px] (default 16)"),
      Field("finest_level", &HornSchunckOptions::finest_level, "finest level solved (default 0)"),
      Field("warm_levels", &HornSchunckOptions::warm_levels,
            "levels solved after a warm start, 0 = all (default 3)"),
      Field("warps", &HornSchunckOptions::warps, "warps per level (default 3)"),
      Field("iterations", &HornSchunckOptions::iterations, "CG iterations per warp (default 20)"),
      Field("tolerance", &HornSchunckOptions::tolerance, "relative CG tolerance (default 1e-3)"));
  BindOptions<LucasKanadeOptions>(
      m, "LucasKanadeOptions", "Options of dense pyramidal Lucas-Kanade.", Args::kKeywordOnly,
      Field("window_sigma", &LucasKanadeOptions::window_sigma,
            "Gaussian window sigma [px] (default 3)"),
      Field("levels", &LucasKanadeOptions::levels, "pyramid levels (default 5)"),
      Field("min_level_size", &LucasKanadeOptions::min_level_size,
            "smallest side of the coarsest level [px] (default 32)"),
      Field("finest_level", &LucasKanadeOptions::finest_level, "finest level solved (default 0)"),
      Field("iterations", &LucasKanadeOptions::iterations, "iterations per level (default 4)"),
      Field("min_eigenvalue", &LucasKanadeOptions::min_eigenvalue,
            "smallest structure-tensor eigenvalue of a valid vector (default 1e-3)"));
  BindOptions<FarnebackOptions>(
      m, "FarnebackOptions", "Options of OpenCV's Farneback flow.", Args::kKeywordOnly,
      Field("pyr_scale", &FarnebackOptions::pyr_scale, "pyramid scale (default 0.5)"),
      Field("levels", &FarnebackOptions::levels, "pyramid levels (default 5)"),
      Field("winsize", &FarnebackOptions::winsize, "averaging window [px] (default 15)"),
      Field("iterations", &FarnebackOptions::iterations, "iterations per level (default 3)"),
      Field("poly_n", &FarnebackOptions::poly_n, "polynomial neighbourhood, 5 or 7 (default 5)"),
      Field("poly_sigma", &FarnebackOptions::poly_sigma, "polynomial sigma [px] (default 1.1)"),
      Field("gaussian_window", &FarnebackOptions::gaussian_window,
            "Gaussian averaging window (default True)"));
  BindOptions<DisOptions>(
      m, "DisOptions", "Options of OpenCV's DIS flow.", Args::kKeywordOnly,
      Field("finest_scale", &DisOptions::finest_scale, "finest level (default 0)"),
      Field("patch_size", &DisOptions::patch_size, "patch size [px] (default 8)"),
      Field("patch_stride", &DisOptions::patch_stride, "patch stride [px] (default 3)"),
      Field("gradient_descent_iterations", &DisOptions::gradient_descent_iterations,
            "iterations per patch (default 25)"),
      Field("variational_refinement_iterations", &DisOptions::variational_refinement_iterations,
            "refinement iterations (default 5)"),
      Field("variational_refinement_alpha", &DisOptions::variational_refinement_alpha,
            "refinement smoothness (default 20)"),
      Field("variational_refinement_delta", &DisOptions::variational_refinement_delta,
            "refinement colour constancy (default 5)"),
      Field("variational_refinement_gamma", &DisOptions::variational_refinement_gamma,
            "refinement gradient constancy (default 10)"),
      Field("use_mean_normalization", &DisOptions::use_mean_normalization,
            "normalise patch means (default True)"),
      Field("use_spatial_propagation", &DisOptions::use_spatial_propagation,
            "spatial propagation (default True)"));
  BindOptions<PivOptions>(
      m, "PivOptions", "Options of window-deformation FFT PIV.", Args::kKeywordOnly,
      Field("window_size", &PivOptions::window_size, "final window [px], even (default 16)"),
      Field("initial_window_size", &PivOptions::initial_window_size,
            "first-pass window [px], even (default 64)"),
      Field("overlap", &PivOptions::overlap, "window overlap fraction (default 0.5)"),
      Field("final_passes", &PivOptions::final_passes, "passes at the final size (default 3)"),
      Field("deform", &PivOptions::deform, "deform the frames between passes (default True)"),
      Field("median_threshold", &PivOptions::median_threshold,
            "normalised median test threshold (default 2)"),
      Field("median_epsilon", &PivOptions::median_epsilon,
            "normalised median test noise level [px] (default 0.1)"),
      Field("min_correlation", &PivOptions::min_correlation,
            "smallest valid peak correlation (default 0.2)"),
      Field("min_mask_fraction", &PivOptions::min_mask_fraction,
            "smallest share of gas pixels in a window (default 0.25)"));
  BindOptions<MedianTestOptions>(
      m, "MedianTestOptions", "Options of the normalised median test.", Args::kKeywordOnly,
      Field("threshold", &MedianTestOptions::threshold, "threshold (default 2)"),
      Field("epsilon", &MedianTestOptions::epsilon, "noise level [px/frame] (default 0.1)"),
      Field("radius", &MedianTestOptions::radius, "neighbourhood radius (default 1)"));
  py::enum_<TemporalStatistic>(m, "TemporalStatistic")
      .value("mean", TemporalStatistic::kMean)
      .value("median", TemporalStatistic::kMedian);
  BindOptions<TemporalFilterOptions>(
      m, "TemporalFilterOptions", "Options of the temporal filter.", Args::kKeywordOnly,
      Field("window", &TemporalFilterOptions::window, "window [frames], odd (default 5)"),
      Field("statistic", &TemporalFilterOptions::statistic, "mean or median (default median)"),
      Field("min_valid_fraction", &TemporalFilterOptions::min_valid_fraction,
            "share of valid frames needed (default 0.5)"));
  BindOptions<PlumeMaskOptions>(
      m, "PlumeMaskOptions", "Options of the plume mask.", Args::kKeywordOnly,
      Field("threshold", &PlumeMaskOptions::threshold, "absolute threshold (default 0)"),
      Field("relative_threshold", &PlumeMaskOptions::relative_threshold,
            "threshold relative to the 99th percentile (default 0.1)"),
      Field("open_radius", &PlumeMaskOptions::open_radius, "opening radius [px] (default 1)"),
      Field("close_radius", &PlumeMaskOptions::close_radius, "closing radius [px] (default 2)"),
      Field("min_area", &PlumeMaskOptions::min_area, "smallest region [px] (default 20)"),
      Field("dilate_radius", &PlumeMaskOptions::dilate_radius, "final dilation [px] (default 2)"));

  py::class_<FlowEstimator>(m, "FlowEstimator",
                            "One flow method with reusable buffers (use "
                            "qogi.velocimetry.FlowEstimator).")
      .def(py::init<const py::object&>(), py::arg("options"))
      .def_property_readonly("method", &FlowEstimator::method)
      .def("set_source_mask", &FlowEstimator::SetSourceMask, py::arg("source_mask"))
      .def("calc", &FlowEstimator::Calc, py::arg("prev"), py::arg("next"),
           py::arg("mask") = py::none(), py::arg("u0") = py::none(), py::arg("v0") = py::none(),
           "(u, v, quality, valid, residual_ratio) for float32 C-contiguous frames.")
      .def("calc_into", &FlowEstimator::CalcInto, py::arg("prev"), py::arg("next"), py::arg("mask"),
           py::arg("warm"), py::arg("u").noconvert(), py::arg("v").noconvert(),
           py::arg("quality").noconvert(), py::arg("valid").noconvert(),
           "residual_ratio; writes u, v, quality (float32) and valid (uint8, 0/1) of the "
           "frames' shape in place; warm: start from this estimator's previous result.");

  m.def("metres_per_second_per_pixel_per_frame", &MetresPerSecondPerPixelPerFrame,
        py::arg("distance_m"), py::arg("ifov_rad"), py::arg("frame_rate_hz"));

  m.def(
      "normalised_median_test",
      [](const FloatArray& u, const FloatArray& v, const ByteArray& valid,
         const MedianTestOptions& o) {
        const cv::Mat mu = FloatMat(u, "u"), mv = FloatMat(v, "v");
        const cv::Mat mk = ByteMat(valid, "valid");
        cv::Mat out;
        {
          py::gil_scoped_release release;
          out = NormalisedMedianTest(mu, mv, mk, o);
        }
        return MatToArray<std::uint8_t>(out);
      },
      py::arg("u"), py::arg("v"), py::arg("valid"), py::arg("options"));

  m.def(
      "replace_vectors",
      [](const FloatArray& u, const FloatArray& v, const ByteArray& keep, int max_distance) {
        const cv::Mat mu = FloatMat(u, "u"), mv = FloatMat(v, "v");
        const cv::Mat mk = ByteMat(keep, "keep");
        cv::Mat ru, rv, filled;
        {
          py::gil_scoped_release release;
          ReplaceVectors(mu, mv, mk, max_distance, ru, rv, filled);
        }
        return py::make_tuple(MatToArray<float>(ru), MatToArray<float>(rv),
                              MatToArray<std::uint8_t>(filled));
      },
      py::arg("u"), py::arg("v"), py::arg("keep"), py::arg("max_distance"));

  m.def(
      "temporal_filter",
      [](const FloatArray& u, const FloatArray& v, const ByteArray& valid,
         const TemporalFilterOptions& o) {
        CheckNdim(u, 3, "u");
        CheckNdim(v, 3, "v");
        CheckNdim(valid, 3, "valid");
        for (int d = 0; d < 3; ++d)
          Require(v.shape(d) == u.shape(d) && valid.shape(d) == u.shape(d),
                  "u, v and valid must have the same (T, H, W) shape");
        const auto su = Slices(u, CV_32FC1), sv = Slices(v, CV_32FC1), sk = Slices(valid, CV_8UC1);
        std::vector<cv::Mat> ou, ov, ok;
        {
          py::gil_scoped_release release;
          TemporalFilter(su, sv, sk, o, ou, ov, ok);
        }
        const py::ssize_t T = u.shape(0), H = u.shape(1), W = u.shape(2);
        py::array_t<float> au({T, H, W}), av({T, H, W});
        py::array_t<std::uint8_t> ak({T, H, W});
        const auto du = Slices(au, CV_32FC1), dv = Slices(av, CV_32FC1), dk = Slices(ak, CV_8UC1);
        for (py::ssize_t t = 0; t < T; ++t) {
          ou[t].copyTo(du[t]);
          ov[t].copyTo(dv[t]);
          ok[t].copyTo(dk[t]);
        }
        return py::make_tuple(au, av, ak);
      },
      py::arg("u"), py::arg("v"), py::arg("valid"), py::arg("options"));

  m.def(
      "frame_velocity",
      [](const FloatArray& u, const FloatArray& v, int num_threads) {
        CheckNdim(u, 3, "u");
        CheckNdim(v, 3, "v");
        for (int d = 0; d < 3; ++d)
          Require(v.shape(d) == u.shape(d), "u and v must have the same (T-1, H, W) shape");
        const auto su = Slices(u, CV_32FC1), sv = Slices(v, CV_32FC1);
        const py::ssize_t T = u.shape(0) + 1, H = u.shape(1), W = u.shape(2);
        py::array_t<float> au({T, H, W}), av({T, H, W});
        auto ou = Slices(au, CV_32FC1), ov = Slices(av, CV_32FC1);
        {
          py::gil_scoped_release release;
          FrameVelocity(su, sv, ou, ov, num_threads);
        }
        return py::make_tuple(au, av);
      },
      py::arg("u"), py::arg("v"), py::arg("num_threads") = 0);

  m.def(
      "invert_displacement",
      [](const FloatArray& u, const FloatArray& v, int iterations) {
        const cv::Mat mu = FloatMat(u, "u"), mv = FloatMat(v, "v");
        cv::Mat bu, bv;
        {
          py::gil_scoped_release release;
          InvertDisplacement(mu, mv, iterations, bu, bv);
        }
        return py::make_tuple(MatToArray<float>(bu), MatToArray<float>(bv));
      },
      py::arg("u"), py::arg("v"), py::arg("iterations"));

  m.def(
      "plume_mask",
      [](const FloatArray& density, const PlumeMaskOptions& o) {
        const cv::Mat d = FloatMat(density, "density");
        cv::Mat out;
        {
          py::gil_scoped_release release;
          out = PlumeMask(d, o);
        }
        return MatToArray<std::uint8_t>(out);
      },
      py::arg("density"), py::arg("options"));

  m.def(
      "set_num_threads",
      [](int n) {
        Require(n >= 0, "num_threads must be >= 0 (0 = all cores); got " + std::to_string(n));
        cv::setNumThreads(n == 0 ? -1 : n);
      },
      py::arg("num_threads"),
      "Threads of the engine's OpenCV pool used by velocimetry (0 = all cores).");
  m.def("get_num_threads", [] { return cv::getNumThreads(); });
}

}  // namespace qogi
