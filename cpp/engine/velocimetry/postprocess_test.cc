// Post-processing: the normalised median test finds planted outliers and
// nothing else, replacement restores a linear field exactly, temporal
// filtering removes a spike, the plume mask follows a known blob, a
// displacement map is inverted, and frame velocities are exact for uniformly
// accelerated trajectories.
#include "engine/velocimetry/postprocess.h"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace qogi {
namespace {

// A smooth field with gradients (u = 0.03 x, v = 1 - 0.02 y) plus seeded
// noise of 0.05 px/frame.
void SmoothField(cv::Mat& u, cv::Mat& v, double noise = 0.05) {
  u.create(40, 50, CV_32F);
  v.create(40, 50, CV_32F);
  cv::RNG rng(42);
  for (int y = 0; y < u.rows; ++y)
    for (int x = 0; x < u.cols; ++x) {
      u.at<float>(y, x) = static_cast<float>(0.03 * x + rng.gaussian(noise));
      v.at<float>(y, x) = static_cast<float>(1.0 - 0.02 * y + rng.gaussian(noise));
    }
}

const std::vector<cv::Point> kPlanted = {{5, 5}, {20, 13}, {33, 30}, {49, 0}, {12, 39}};

TEST(MedianTest, FindsExactlyThePlantedOutliers) {
  cv::Mat u, v;
  SmoothField(u, v);
  for (std::size_t i = 0; i < kPlanted.size(); ++i) {
    // Half in u, half in v; 1.5 px is 30 times the noise.
    (i % 2 ? v : u).at<float>(kPlanted[i]) += 1.5f;
  }
  const cv::Mat valid = cv::Mat::ones(u.size(), CV_8U);
  const cv::Mat out = NormalisedMedianTest(u, v, valid);
  EXPECT_EQ(cv::countNonZero(out), static_cast<int>(kPlanted.size()));
  for (const auto& p : kPlanted) EXPECT_EQ(out.at<uchar>(p), 1) << p;
}

TEST(MedianTest, InvalidVectorsAreNeitherTestedNorUsed) {
  cv::Mat u, v;
  SmoothField(u, v, 0.0);
  cv::Mat valid = cv::Mat::ones(u.size(), CV_8U);
  // An invalid garbage vector must not flag its valid neighbours...
  u.at<float>(10, 10) = 1000.f;
  valid.at<uchar>(10, 10) = 0;
  // ...nor be reported itself.
  const cv::Mat out = NormalisedMedianTest(u, v, valid);
  EXPECT_EQ(cv::countNonZero(out), 0);
}

TEST(MedianTest, RejectsBadInput) {
  cv::Mat u, v;
  SmoothField(u, v);
  EXPECT_THROW(NormalisedMedianTest(u, v, cv::Mat::ones(3, 3, CV_8U)), std::invalid_argument);
  MedianTestOptions o;
  o.threshold = -1;
  try {
    NormalisedMedianTest(u, v, cv::Mat::ones(u.size(), CV_8U), o);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("MedianTestOptions.threshold"), std::string::npos);
  }
}

TEST(ReplaceVectors, RestoresALinearFieldAndMarksWhatItFilled) {
  cv::Mat u, v;
  SmoothField(u, v, 0.0);
  cv::Mat keep = cv::Mat::ones(u.size(), CV_8U);
  cv::Mat damaged_u = u.clone(), damaged_v = v.clone();
  // A 3 x 3 hole and two single vectors, overwritten with garbage.
  cv::rectangle(keep, cv::Rect(20, 20, 3, 3), cv::Scalar(0), -1);
  keep.at<uchar>(5, 30) = keep.at<uchar>(35, 7) = 0;
  damaged_u.setTo(99.f, keep == 0);
  damaged_v.setTo(-99.f, keep == 0);
  cv::Mat ru, rv, filled;
  ReplaceVectors(damaged_u, damaged_v, keep, 0, ru, rv, filled);
  EXPECT_EQ(cv::countNonZero(filled), 11);
  // An isolated vector has its full ring of 8: for a linear field the ring's
  // median is exactly the centre value.
  for (const cv::Point p : {cv::Point(30, 5), cv::Point(7, 35)}) {
    EXPECT_NEAR(ru.at<float>(p), u.at<float>(p), 1e-5);
    EXPECT_NEAR(rv.at<float>(p), v.at<float>(p), 1e-5);
  }
  // In the hole the neighbours are one-sided: off by at most one pixel's
  // change of the field (0.03 in u, 0.02 in v).
  EXPECT_LE(cv::norm(ru, u, cv::NORM_INF), 0.03 + 1e-5);
  EXPECT_LE(cv::norm(rv, v, cv::NORM_INF), 0.02 + 1e-5);
  EXPECT_EQ(damaged_u.at<float>(5, 30), 99.f);  // input untouched
}

TEST(ReplaceVectors, StopsAtMaxDistance) {
  cv::Mat u = cv::Mat::zeros(1, 10, CV_32F), v = cv::Mat::zeros(1, 10, CV_32F);
  cv::Mat keep = cv::Mat::zeros(1, 10, CV_8U);
  keep.at<uchar>(0, 0) = 1;
  u.at<float>(0, 0) = 2.f;
  cv::Mat ru, rv, filled;
  ReplaceVectors(u, v, keep, 3, ru, rv, filled);
  EXPECT_EQ(cv::countNonZero(filled), 3);
  EXPECT_EQ(ru.at<float>(0, 3), 2.f);
  EXPECT_EQ(ru.at<float>(0, 4), 0.f);
}

TEST(TemporalFilter, MedianRemovesASpikeAndMeanAverages) {
  const int T = 7;
  std::vector<cv::Mat> u, v, valid;
  for (int t = 0; t < T; ++t) {
    u.push_back(cv::Mat(4, 5, CV_32F, cv::Scalar(static_cast<double>(t))));
    v.push_back(cv::Mat(4, 5, CV_32F, cv::Scalar(1.0)));
    valid.push_back(cv::Mat::ones(4, 5, CV_8U));
  }
  v[3].at<float>(2, 2) = 50.f;  // a spike
  std::vector<cv::Mat> fu, fv, fvalid;
  TemporalFilterOptions o;  // median over 5 frames
  TemporalFilter(u, v, valid, o, fu, fv, fvalid);
  EXPECT_FLOAT_EQ(fv[3].at<float>(2, 2), 1.f);
  EXPECT_FLOAT_EQ(fu[3].at<float>(0, 0), 3.f);
  EXPECT_FLOAT_EQ(fu[0].at<float>(0, 0), 1.f);  // window shortened: frames 0-2
  o.statistic = TemporalStatistic::kMean;
  TemporalFilter(u, v, valid, o, fu, fv, fvalid);
  EXPECT_FLOAT_EQ(fv[3].at<float>(2, 2), (4 * 1.f + 50.f) / 5);
  EXPECT_FLOAT_EQ(fu[6].at<float>(1, 1), 5.f);  // frames 4-6
}

TEST(TemporalFilter, UsesOnlyValidVectorsAndRequiresEnough) {
  const int T = 5;
  std::vector<cv::Mat> u, v, valid;
  for (int t = 0; t < T; ++t) {
    u.push_back(cv::Mat(2, 2, CV_32F, cv::Scalar(t == 2 ? 100.0 : 1.0)));
    v.push_back(cv::Mat::zeros(2, 2, CV_32F));
    valid.push_back(cv::Mat(2, 2, CV_8U, cv::Scalar(t == 2 ? 0 : 1)));
  }
  valid[1].at<uchar>(0, 0) = valid[3].at<uchar>(0, 0) = 0;  // only 2 of 5 left there
  std::vector<cv::Mat> fu, fv, fvalid;
  TemporalFilterOptions o;
  o.statistic = TemporalStatistic::kMean;
  TemporalFilter(u, v, valid, o, fu, fv, fvalid);
  EXPECT_FLOAT_EQ(fu[2].at<float>(1, 1), 1.f);  // the invalid 100 is ignored
  EXPECT_EQ(fvalid[2].at<uchar>(1, 1), 1);
  EXPECT_EQ(fvalid[2].at<uchar>(0, 0), 0);      // 2 / 5 < min_valid_fraction
}

TEST(PlumeMask, FollowsABlobAndDropsSpecks) {
  // Gaussian blob of peak 1 (sigma 12 px) on noise of 0.01, plus a 2 x 2 speck.
  cv::Mat rho(120, 160, CV_32F);
  cv::RNG rng(3);
  for (int y = 0; y < rho.rows; ++y)
    for (int x = 0; x < rho.cols; ++x) {
      const double r2 = (x - 80.0) * (x - 80.0) + (y - 60.0) * (y - 60.0);
      rho.at<float>(y, x) = static_cast<float>(std::exp(-r2 / (2 * 144.0)) + rng.gaussian(0.01));
    }
  rho(cv::Rect(10, 10, 2, 2)).setTo(0.9);
  PlumeMaskOptions o;
  o.threshold = 0.25;         // above the relative one (0.1 x ~1)
  o.dilate_radius = 0;
  const cv::Mat mask = PlumeMask(rho, o);
  // exp(-r^2 / 2 sigma^2) >= 0.25  <=>  r <= sigma sqrt(2 ln 4) = 19.98 px
  const double area = M_PI * 19.98 * 19.98;
  EXPECT_NEAR(cv::countNonZero(mask), area, 0.05 * area);
  EXPECT_EQ(mask.at<uchar>(10, 10), 0);
  EXPECT_EQ(mask.at<uchar>(60, 80), 1);
  o.dilate_radius = 3;
  EXPECT_GT(cv::countNonZero(PlumeMask(rho, o)), cv::countNonZero(mask));
}

TEST(InvertDisplacement, MapsBackARotationAndDrift) {
  // phi(x) = c + R (x - c) + d; its inverse is c + R^T (x - c - d).
  const int W = 96, H = 80;
  const double th = 0.05, cx = 47.5, cy = 39.5, dx = 2.5, dy = -1.5;
  cv::Mat u(H, W, CV_32F), v(H, W, CV_32F);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const double rx = x - cx, ry = y - cy;
      u.at<float>(y, x) = static_cast<float>(cx + std::cos(th) * rx - std::sin(th) * ry + dx - x);
      v.at<float>(y, x) = static_cast<float>(cy + std::sin(th) * rx + std::cos(th) * ry + dy - y);
    }
  cv::Mat bu, bv;
  InvertDisplacement(u, v, 20, bu, bv);
  double worst = 0;
  for (int y = 10; y < H - 10; ++y)
    for (int x = 10; x < W - 10; ++x) {
      const double rx = x - cx - dx, ry = y - cy - dy;
      const double ex = cx + std::cos(th) * rx + std::sin(th) * ry - x;
      const double ey = cy - std::sin(th) * rx + std::cos(th) * ry - y;
      worst =
          std::max({worst, std::abs(bu.at<float>(y, x) - ex), std::abs(bv.at<float>(y, x) - ey)});
    }
  EXPECT_LT(worst, 2e-3);
  EXPECT_THROW(InvertDisplacement(u, v, 0, bu, bv), std::invalid_argument);
}

TEST(FrameVelocity, ExactForUniformAccelerationWhereThePairDisplacementIsNot) {
  // Gas rising with y(t) = y0 - (a t + g t^2 / 2), a = 1.5 px/frame, g = 0.8
  // px/frame^2 along rows, everywhere: pair k displaces by a + g (k + 1/2),
  // the velocity at frame t is a + g t.
  const int W = 64, H = 48, T = 5;
  const double a = 1.5, g = 0.8;
  std::vector<cv::Mat> u(T - 1), v(T - 1);
  for (int k = 0; k < T - 1; ++k) {
    u[k] = cv::Mat::zeros(H, W, CV_32F);
    v[k] = cv::Mat(H, W, CV_32F, cv::Scalar(-(a + g * (k + 0.5))));
  }
  std::vector<cv::Mat> fu, fv;
  FrameVelocity(u, v, fu, fv);
  ASSERT_EQ(fu.size(), static_cast<std::size_t>(T));
  for (int t = 1; t < T - 1; ++t) {
    EXPECT_NEAR(fv[t].at<float>(24, 32), -(a + g * t), 1e-4) << t;
    EXPECT_NEAR(fu[t].at<float>(24, 32), 0.0, 1e-6);
    // The pair displacement alone is off by g / 2.
    EXPECT_NEAR(v[t].at<float>(24, 32) - fv[t].at<float>(24, 32), -0.5 * g, 1e-4);
  }
  EXPECT_NEAR(fv[0].at<float>(24, 32), -(a + 0.5 * g), 1e-6);  // one-sided ends
  EXPECT_NEAR(fv[T - 1].at<float>(24, 32), -(a + g * (T - 1.5)), 1e-4);
  std::vector<cv::Mat> none;
  EXPECT_THROW(FrameVelocity(none, none, fu, fv), std::invalid_argument);
}

}  // namespace
}  // namespace qogi
