// Bindings of engine/registration: the options struct (same field names as in
// C++), a registration object per reference, and the two resamplings. Glue only.
#include "common.h"

#include <opencv2/core.hpp>

#include "engine/registration/registration.h"

namespace qogi {
namespace {

using ByteArray = py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast>;

cv::Mat ImageMat(const FloatArray& a, const char* name) {
  CheckNdim(a, 2, name);
  return cv::Mat(static_cast<int>(a.shape(0)), static_cast<int>(a.shape(1)), CV_32FC1,
                 const_cast<float*>(a.data()));
}

py::dict ShiftDict(const RigidShift& s) {
  return ToDict(s, Field("dx_px", &RigidShift::dx_px), Field("dy_px", &RigidShift::dy_px),
                Field("angle_rad", &RigidShift::angle_rad));
}

RigidShift ShiftOf(double dx, double dy, double angle) {
  CheckFinite(dx, "dx_px");
  CheckFinite(dy, "dy_px");
  CheckFinite(angle, "angle_rad");
  return RigidShift{dx, dy, angle};
}

// (C, H, W) or (H, W) float32 frames, each image resampled by `one`.
template <typename Fn>
py::array_t<float> EachImage(const FloatArray& frames, Fn one) {
  Require(frames.ndim() == 2 || frames.ndim() == 3,
          "frame must be (H, W) or (C, H, W) float32; got shape " + ShapeOf(frames));
  const int c = frames.ndim() == 3 ? static_cast<int>(frames.shape(0)) : 1;
  const int h = static_cast<int>(frames.shape(frames.ndim() - 2));
  const int w = static_cast<int>(frames.shape(frames.ndim() - 1));
  py::array_t<float> out(std::vector<py::ssize_t>(frames.shape(), frames.shape() + frames.ndim()));
  float* dst = out.mutable_data();
  const float* src = frames.data();
  {
    py::gil_scoped_release release;
    for (int k = 0; k < c; ++k) {
      const cv::Mat in(h, w, CV_32FC1, const_cast<float*>(src + std::size_t(k) * h * w));
      cv::Mat res(h, w, CV_32FC1, dst + std::size_t(k) * h * w);
      cv::Mat tmp;
      one(in, &tmp);
      tmp.copyTo(res);
    }
  }
  return out;
}

}  // namespace

void BindRegistration(py::module_& m) {
  BindOptions<RegistrationOptions>(
      m, "RegistrationOptions",
      "Options of the rigid frame registration (engine/registration/registration.h).",
      Args::kKeywordOnly,
      Field("rotation", &RegistrationOptions::rotation,
            "also estimate a rotation about the image centre (default True)"),
      Field("max_iterations", &RegistrationOptions::max_iterations,
            "Gauss-Newton iterations at most, 1-200 (default 30)"),
      Field("tolerance_px", &RegistrationOptions::tolerance_px,
            "stop when an update moves no pixel by more than this [px], > 0 (default 1e-3)"),
      Field("robust_scale", &RegistrationOptions::robust_scale,
            "Tukey biweight cut-off in units of the residual's robust spread, > 0 "
            "(default 4.685)"),
      Field("border_px", &RegistrationOptions::border_px,
            "pixels along each edge left out of the fit, >= 0 (default 4)"),
      Field("max_shift_px", &RegistrationOptions::max_shift_px,
            "a larger shift is reported not converged [px], > 0 (default 8)"),
      Field("smoothing_px", &RegistrationOptions::smoothing_px,
            "Gaussian smoothing of reference and frame before the fit [px sigma], 0-20 "
            "(default 1)"));

  py::class_<FrameRegistration>(
      m, "FrameRegistration",
      "Rigid registration of frames to a reference image of the static scene: the "
      "frame's content at W(x) = R(angle)(x - c) + c + (dx, dy) equals the reference's "
      "at x (c the image centre, x right, y down).")
      .def(py::init([](const FloatArray& reference, const py::object& mask,
                       const RegistrationOptions& options) {
             const cv::Mat ref = ImageMat(reference, "reference");
             cv::Mat m;
             ByteArray keep;
             if (!mask.is_none()) {
               keep = mask.cast<ByteArray>();
               CheckNdim(keep, 2, "mask");
               m = cv::Mat(static_cast<int>(keep.shape(0)), static_cast<int>(keep.shape(1)),
                           CV_8UC1, const_cast<std::uint8_t*>(keep.data()));
             }
             return FrameRegistration(ref, m, options);  // copies what it keeps
           }),
           py::arg("reference"), py::arg("mask") = py::none(),
           py::arg("options") = RegistrationOptions{})
      .def(
          "register",
          [](const FrameRegistration& self, const FloatArray& frame, double dx, double dy,
             double angle) {
            const cv::Mat f = ImageMat(frame, "frame");
            const RigidShift start = ShiftOf(dx, dy, angle);
            RegistrationResult r;
            {
              py::gil_scoped_release release;
              r = self.Register(f, start);
            }
            py::dict d = ShiftDict(r.shift);
            d["sigma"] = ShiftDict(r.sigma);
            d["residual_sigma"] = r.residual_sigma;
            d["inlier_fraction"] = r.inlier_fraction;
            d["iterations"] = r.iterations;
            d["converged"] = r.converged;
            return d;
          },
          py::arg("frame"), py::arg("dx_px") = 0.0, py::arg("dy_px") = 0.0,
          py::arg("angle_rad") = 0.0,
          "The frame's rigid motion from the reference, starting from (dx_px, dy_px, "
          "angle_rad): dict dx_px, dy_px [px], angle_rad, sigma (their 1-sigma precision), "
          "residual_sigma [image units], inlier_fraction, iterations, converged.")
      .def(
          "precision",
          [](const FrameRegistration& self, double noise_sigma) {
            return ShiftDict(self.Precision(noise_sigma));
          },
          py::arg("noise_sigma"),
          "1-sigma precision of dx_px, dy_px, angle_rad for white noise of noise_sigma "
          "[image units] per pixel (large where the scene's texture does not fix a parameter).")
      .def_property_readonly(
          "options", [](const FrameRegistration& self) { return self.options(); },
          py::return_value_policy::copy);

  m.def(
      "warp_to_reference",
      [](const FloatArray& frame, double dx, double dy, double angle) {
        const RigidShift s = ShiftOf(dx, dy, angle);
        return EachImage(frame,
                         [&](const cv::Mat& in, cv::Mat* out) { WarpToReference(in, s, out); });
      },
      py::arg("frame"), py::arg("dx_px"), py::arg("dy_px"), py::arg("angle_rad") = 0.0,
      "frame ((H, W) or (C, H, W) float32) resampled into the reference's geometry: "
      "out(x) = frame(W(x)) (bicubic, border replicated); a new array.");
  m.def(
      "warp_along_flow",
      [](const FloatArray& frame, const FloatArray& u, const FloatArray& v, double scale) {
        const cv::Mat um = ImageMat(u, "u"), vm = ImageMat(v, "v");
        return EachImage(
            frame, [&](const cv::Mat& in, cv::Mat* out) { WarpAlongFlow(in, um, vm, scale, out); });
      },
      py::arg("frame"), py::arg("u"), py::arg("v"), py::arg("scale"),
      "frame ((H, W) or (C, H, W) float32) moved along a displacement field: "
      "out(x) = frame(x + scale (u, v)(x)) [u, v px, float32 (H, W)] (bicubic, border "
      "replicated); a new array.");
}

}  // namespace qogi
