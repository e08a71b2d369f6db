#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>

#include "engine/velocimetry/fluid_flow.h"
#include "engine/velocimetry/horn_schunck.h"
#include "engine/velocimetry/lucas_kanade.h"
#include "engine/velocimetry/opencv_flow.h"
#include "engine/velocimetry/piv.h"
#include "engine/velocimetry/postprocess.h"
#include "engine/velocimetry/moving_texture_test.h"
#include <opencv2/imgproc.hpp>
#include "engine/velocimetry/image_ops.h"

namespace qogi {
namespace {
using testing_scenes::Motion;
using testing_scenes::Scene;
using testing_scenes::Texture;

const cv::Size kSize(std::getenv("BIG") ? 320 : 192, std::getenv("BIG") ? 256 : 160);

double RunMethod(OpticalFlow& m, const Scene& s, int margin, double* frac, const cv::Mat& region = cv::Mat()) {
  FlowField f;
  if (std::getenv("BENCH")) {
    int reps = std::atoi(std::getenv("BENCH"));
    m.Calc(s.prev, s.next, f);
    auto cpu = [] { timespec ts; clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts); return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6; };
    double c0 = cpu();
    auto b0 = std::chrono::steady_clock::now();
    for (int i = 0; i < reps; ++i) { FlowField g; m.Calc(s.prev, s.next, g); }
    auto b1 = std::chrono::steady_clock::now();
    double c1 = cpu();
    std::printf("  bench %s cold: %.2f ms (thread cpu %.2f ms)\n", FlowMethodName(m.method()), std::chrono::duration<double, std::milli>(b1 - b0).count() / reps, (c1 - c0) / reps);
    FlowField g; m.Calc(s.prev, s.next, g);
    b0 = std::chrono::steady_clock::now();
    for (int i = 0; i < reps; ++i) { m.Calc(s.prev, s.next, g); }
    b1 = std::chrono::steady_clock::now();
    std::printf("  bench %s warm: %.2f ms\n", FlowMethodName(m.method()), std::chrono::duration<double, std::milli>(b1 - b0).count() / reps);
  }
  auto t0 = std::chrono::steady_clock::now();
  m.Calc(s.prev, s.next, f);
  auto t1 = std::chrono::steady_clock::now();
  double e = testing_scenes::MeanEndPointError(f.u, f.v, f.valid, s, margin, frac, region);
  std::printf("%s: epe %.4f valid %.3f ratio %.4f  %.2f ms\n", FlowMethodName(m.method()), e,
              *frac, f.residual_ratio,
              std::chrono::duration<double, std::milli>(t1 - t0).count());
  if (!region.empty()) {
    cv::Mat ux, uy, vx, vy, tux, tuy, tvx, tvy;
    flow_ops::CentralGradient(f.u, ux, uy); flow_ops::CentralGradient(f.v, vx, vy);
    flow_ops::CentralGradient(s.true_u, tux, tuy); flow_ops::CentralGradient(s.true_v, tvx, tvy);
    cv::Mat div = ux + vy, tdiv = tux + tvy;
    double md = cv::mean(div, region)[0], mt = cv::mean(tdiv, region)[0];
    cv::Mat du = f.u - s.true_u, dv = f.v - s.true_v;
    std::printf("    mean div %.4f true %.4f  (ratio %.3f); mean err u %.4f v %.4f\n", md, mt, md / mt, cv::mean(du, region)[0], cv::mean(dv, region)[0]);
  }
  if (std::getenv("DUMP")) {
    for (int y = 8; y < s.prev.rows; y += 16) {
      std::printf("y=%3d:", y);
      for (int x = 8; x < s.prev.cols; x += 16)
        std::printf(" %+.2f,%+.2f", f.u.at<float>(y, x) - s.true_u.at<float>(y, x),
                    f.v.at<float>(y, x) - s.true_v.at<float>(y, x));
      std::printf("\n");
    }
  }
  return e;
}

TEST(Explore, All) {
  if (std::getenv("THREADS")) cv::setNumThreads(std::atoi(std::getenv("THREADS")));
  Texture t = Texture::Make(7);
  std::vector<std::pair<const char*, Motion>> motions = {
      {"translation", Motion::Translation(2.3, -1.4)},
      {"rotation", Motion::Rotation(3.0 / 125.0, kSize.width / 2.0, kSize.height / 2.0)},
      {"jet", Motion::JetShear(2.5, 80, 25)},
  };
  std::vector<std::pair<const char*, Motion>> dens = {
      {"spreading", Motion::Spreading(0.015, kSize.width / 2.0, kSize.height / 2.0)},
      {"source", Motion::DriftingSource(0.05, kSize.width / 2.0, kSize.height / 2.0, 30, 1.5, -0.8)},
      {"vortex", Motion::DriftingVortex(1.5, kSize.width / 2.0, kSize.height / 2.0, 30, 1.0, 0.5)},
  };
  int ndens = std::getenv("NODENS") ? 0 : 3;
  for (int i = 0; i < (int)motions.size() + ndens; ++i) {
    bool d = i >= (int)motions.size();
    auto& [name, m] = d ? dens[i - motions.size()] : motions[i];
    Scene s = d ? testing_scenes::RenderDensity(kSize, t, m, kSize.width / 2.0, kSize.height / 2.0, 50, std::getenv("NOISE") ? std::atof(std::getenv("NOISE")) : 0.01, 3, std::getenv("CONTRAST") ? std::atof(std::getenv("CONTRAST")) : 0.4)
                : testing_scenes::RenderTexture(kSize, t, m, 0.01, 3);
    cv::Mat region;
    if (d) {
      region = cv::Mat::zeros(kSize, CV_8U);
      cv::circle(region, cv::Point(kSize.width / 2, kSize.height / 2), 60, cv::Scalar(1), -1);
    }
    std::printf("== %s\n", name);
    double frac;
    FluidFlowOptions fo;
    auto env = [](const char* k, double d) { const char* v = std::getenv(k); return v ? std::atof(v) : d; };
    fo.alpha = env("FL_ALPHA", fo.alpha);
    fo.alpha_div = env("FL_DIV", fo.alpha_div);
    fo.alpha_curl = env("FL_CURL", fo.alpha_curl);
    fo.div_curl_scale = env("FL_SCALE", fo.div_curl_scale);
    fo.iterations = (int)env("FL_ITERS", fo.iterations);
    fo.warps = (int)env("FL_WARPS", fo.warps);
    fo.finest_level = (int)env("FL_FINEST", fo.finest_level);
    HornSchunckOptions ho;
    ho.alpha = env("HS_ALPHA", ho.alpha);
    FluidFlow fl(fo);
    RunMethod(fl, s, 16, &frac, region);
    HornSchunckFlow hs(ho);
    if (!std::getenv("NOHS")) RunMethod(hs, s, 16, &frac, region);
    if (std::getenv("OTHERS")) {
      LucasKanadeFlow lk; RunMethod(lk, s, 16, &frac, region);
      FarnebackFlow fb; RunMethod(fb, s, 16, &frac, region);
      DisFlow dis; RunMethod(dis, s, 16, &frac, region);
      PivFlow piv; RunMethod(piv, s, 16, &frac, region);
    }
  }
}

}  // namespace
}  // namespace qogi

namespace qogi {
namespace {
TEST(Explore, Column) {
  Texture t = Texture::Make(11);
  const cv::Size size(128, 192);
  const double noise = std::getenv("NOISE") ? std::atof(std::getenv("NOISE")) : 0.005;
  Scene s = testing_scenes::RenderSteadyColumn(size, t, 180, 64, 12, 3.0, 0.008, 25, 0.3, noise, 5);
  cv::Mat mask = PlumeMask(s.prev);
  std::printf("mask area %d\n", cv::countNonZero(mask));
  cv::Mat base = cv::Mat::zeros(size, CV_8U), top = cv::Mat::zeros(size, CV_8U);
  cv::rectangle(base, cv::Rect(64 - 12, 180 - 55, 25, 50), cv::Scalar(1), -1);
  cv::rectangle(top, cv::Rect(64 - 12, 180 - 170, 25, 80), cv::Scalar(1), -1);
  auto report = [&](OpticalFlow& m, const cv::Mat& msk, const char* tag) {
    FlowField f;
    m.Calc(s.prev, s.next, f, msk);
    cv::Mat dv = f.v - s.true_v;
    std::printf("%-13s %-8s base: v %.3f true %.3f | top: v %.3f true %.3f\n", FlowMethodName(m.method()), tag,
                cv::mean(f.v, base)[0], cv::mean(s.true_v, base)[0], cv::mean(f.v, top)[0], cv::mean(s.true_v, top)[0]);
  };
  FluidFlowOptions fo;
  auto env = [](const char* k, double d) { const char* v = std::getenv(k); return v ? std::atof(v) : d; };
  fo.alpha = env("FL_ALPHA", fo.alpha);
  fo.alpha_div = env("FL_DIV", fo.alpha_div);
  fo.finest_level = (int)env("FL_FINEST", fo.finest_level);
  fo.iterations = (int)env("FL_ITERS", fo.iterations);
  fo.warps = (int)env("FL_WARPS", fo.warps);
  FluidFlow fl(fo);
  report(fl, mask, "mask");
  report(fl, cv::Mat(), "nomask");
  cv::Mat src = cv::Mat::zeros(size, CV_8U);
  cv::rectangle(src, cv::Rect(0, 179, 128, 3), cv::Scalar(1), -1);
  fl.set_source_mask(src);
  report(fl, mask, "source");
  {
    FlowField f;
    for (int k = 0; k < 6; ++k) {
      fl.Calc(s.prev, s.next, f, mask);
      std::printf("  warm %d: base v %.3f top %.3f\n", k, cv::mean(f.v, base)[0], cv::mean(f.v, top)[0]);
    }
  }
  HornSchunckFlow hs; report(hs, mask, "mask");
  LucasKanadeFlow lk; report(lk, mask, "mask");
  FarnebackFlow fb; report(fb, mask, "mask");
  DisFlow dis; report(dis, mask, "mask");
  PivFlow piv; report(piv, mask, "mask");
}
}  // namespace
}  // namespace qogi
namespace qogi {
namespace {
TEST(Explore, ColumnTruthResidual) {
  Texture t = Texture::Make(11);
  const cv::Size size(128, 192);
  Scene s = testing_scenes::RenderSteadyColumn(size, t, 180, 64, 12, 3.0, 0.008, 25, 0.3, 0.0, 5);
  cv::Mat warped, ux, uy, vx, vy;
  flow_ops::Warp(s.next, s.true_u, s.true_v, warped);
  flow_ops::CentralGradient(s.true_u, ux, uy);
  flow_ops::CentralGradient(s.true_v, vx, vy);
  for (int y = 20; y < 192; y += 10) {
    int x = 64;
    float j = (1 + ux.at<float>(y, x)) * (1 + vy.at<float>(y, x)) - uy.at<float>(y, x) * vx.at<float>(y, x);
    float r = warped.at<float>(y, x) * j - s.prev.at<float>(y, x);
    std::printf("y %3d rho0 %.4f rho1 %.4f v %.3f J %.4f r %.5f  rbc %.5f\n", y, s.prev.at<float>(y, x), s.next.at<float>(y, x), s.true_v.at<float>(y, x), j, r, warped.at<float>(y, x) - s.prev.at<float>(y, x));
  }
  FluidFlowOptions fo; fo.iterations = 200; fo.warps = 3;
  FluidFlow fl(fo);
  FlowField f;
  fl.Calc(s.prev, s.next, f, PlumeMask(s.prev));
  for (int y = 20; y < 192; y += 10) {
    std::printf("y %3d v_est %.3f true %.3f | u at x=40,52,64,76,88: %.3f %.3f %.3f %.3f %.3f | v side %.3f %.3f\n", y, f.v.at<float>(y, 64), s.true_v.at<float>(y, 64),
       f.u.at<float>(y, 40), f.u.at<float>(y, 52), f.u.at<float>(y, 64), f.u.at<float>(y, 76), f.u.at<float>(y, 88), f.v.at<float>(y, 40), f.v.at<float>(y, 88));
  }
}
}  // namespace
}  // namespace qogi
