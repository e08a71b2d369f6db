// The held pixels' image operations: components, a disk's morphology,
// resizing and the Navier-Stokes inpainting, against what they must give
// on images whose answer is known, and their refusals.
#include "engine/background/held_pixels.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace qogi {
namespace {

TEST(HeldPixels, ComponentsAreEightConnected) {
  cv::Mat m = cv::Mat::zeros(10, 10, CV_8UC1);
  m.at<uchar>(1, 1) = m.at<uchar>(2, 2) = 1;  // diagonal neighbours: one component
  m.at<uchar>(7, 7) = m.at<uchar>(7, 8) = 1;  // another
  cv::Mat labels;
  EXPECT_EQ(ConnectedComponents8(m, &labels), 3);  // background + 2
  EXPECT_EQ(labels.type(), CV_32SC1);
  EXPECT_EQ(labels.at<int>(1, 1), labels.at<int>(2, 2));
  EXPECT_NE(labels.at<int>(1, 1), labels.at<int>(7, 7));
  EXPECT_EQ(labels.at<int>(0, 0), 0);
}

TEST(HeldPixels, DilatingOnePixelGivesTheDisk) {
  cv::Mat m = cv::Mat::zeros(21, 21, CV_8UC1);
  m.at<uchar>(10, 10) = 7;  // any nonzero value is inside
  cv::Mat d;
  DilateDisk(m, 3, &d);
  const cv::Mat disk = DiskElement(3);
  ASSERT_EQ(disk.rows, 7);
  EXPECT_EQ(cv::countNonZero(d), cv::countNonZero(disk));
  EXPECT_EQ(d.at<uchar>(10, 13), 1);  // the disk's edge, on the axis
  EXPECT_EQ(d.at<uchar>(13, 13), 0);  // not its corner
  double hi = 0;
  cv::minMaxLoc(d, nullptr, &hi);
  EXPECT_EQ(hi, 1.0);
}

TEST(HeldPixels, OpeningRemovesLinesNarrowerThanTheDisk) {
  cv::Mat m = cv::Mat::zeros(40, 40, CV_8UC1);
  m(cv::Rect(5, 5, 12, 12)).setTo(1);  // a block: kept
  m(cv::Rect(25, 2, 1, 36)).setTo(1);  // a 1 px seam: removed
  cv::Mat o;
  OpenDisk(m, 2, &o);
  EXPECT_EQ(o.at<uchar>(10, 10), 1);
  EXPECT_EQ(cv::countNonZero(o.col(25)), 0);
}

TEST(HeldPixels, AreaResizeAveragesAndLinearResizeKeepsAPlane) {
  cv::Mat img(4, 4, CV_32FC1);
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 4; ++x) img.at<float>(y, x) = float(x + 4 * y);
  cv::Mat half;
  ResizeImage(img, 2, 2, ResizeMode::kArea, &half);
  EXPECT_FLOAT_EQ(half.at<float>(0, 0), (0 + 1 + 4 + 5) / 4.0f);
  EXPECT_FLOAT_EQ(half.at<float>(1, 1), (10 + 11 + 14 + 15) / 4.0f);
  cv::Mat up;
  ResizeImage(half, 4, 4, ResizeMode::kLinear, &up);
  EXPECT_EQ(up.size(), img.size());
  // A plane averaged down and interpolated back is the plane (away from the
  // border, pixel centres at half pixels): x + 4 y at (1, 1) and (2, 2).
  EXPECT_NEAR(up.at<float>(1, 1), 5.0f, 1e-4);
  EXPECT_NEAR(up.at<float>(2, 2), 10.0f, 1e-4);
}

TEST(HeldPixels, InpaintingFillsAHoleInASmoothRampCloseToTheRamp) {
  cv::Mat img(40, 40, CV_32FC1), mask = cv::Mat::zeros(40, 40, CV_8UC1);
  for (int y = 0; y < 40; ++y)
    for (int x = 0; x < 40; ++x) img.at<float>(y, x) = 0.5f * x + 0.25f * y;
  cv::Mat holed = img.clone();
  holed(cv::Rect(15, 15, 8, 8)).setTo(100.0f);  // garbage where held
  mask(cv::Rect(15, 15, 8, 8)).setTo(1);
  cv::Mat filled;
  InpaintNavierStokes(holed, mask, 3.0, &filled);
  double worst = 0;
  for (int y = 15; y < 23; ++y)
    for (int x = 15; x < 23; ++x)
      worst = std::max(worst, double(std::abs(filled.at<float>(y, x) - img.at<float>(y, x))));
  // Within a quarter of the ramp's change across the hole (8 x 0.5 + 8 x 0.25 = 6;
  // the inpainting is diffusive, not exact on a plane); the garbage was 100.
  EXPECT_LT(worst, 1.5);
  EXPECT_FLOAT_EQ(filled.at<float>(0, 0), img.at<float>(0, 0));  // outside: untouched
}

TEST(HeldPixels, RefusesWrongTypesSizesAndRadii) {
  cv::Mat f = cv::Mat::zeros(8, 8, CV_32FC1), m = cv::Mat::zeros(8, 8, CV_8UC1), out;
  EXPECT_THROW(ConnectedComponents8(f, &out), std::invalid_argument);
  EXPECT_THROW(DilateDisk(m, -1, &out), std::invalid_argument);
  EXPECT_THROW(ResizeImage(m, 4, 4, ResizeMode::kArea, &out), std::invalid_argument);
  EXPECT_THROW(ResizeImage(f, 0, 4, ResizeMode::kArea, &out), std::invalid_argument);
  EXPECT_THROW(InpaintNavierStokes(f, cv::Mat::zeros(4, 4, CV_8UC1), 3.0, &out),
               std::invalid_argument);
  EXPECT_THROW(InpaintNavierStokes(f, m, 0.0, &out), std::invalid_argument);
}

}  // namespace
}  // namespace qogi
