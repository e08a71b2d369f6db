#include "engine/background/held_pixels.h"

#include <string>

#include <opencv2/imgproc.hpp>
#include <opencv2/photo.hpp>

#include "engine/util/check.h"

namespace qogi {
namespace {

void RequireMask(const cv::Mat& mask, const char* what) {
  Require(!mask.empty() && mask.type() == CV_8UC1,
          std::string(what) + ": the mask must be a non-empty 8-bit single-channel image");
}

void RequireImage(const cv::Mat& image, const char* what) {
  Require(!image.empty() && image.type() == CV_32FC1,
          std::string(what) + ": the image must be a non-empty float32 single-channel image");
}

void RequireRadius(int radius, const char* what) {
  Require(
      radius >= 0 && radius <= 1000,
      std::string(what) + ": the radius must be within 0-1000 px; got " + std::to_string(radius));
}

}  // namespace

int ConnectedComponents8(const cv::Mat& mask, cv::Mat* labels) {
  RequireMask(mask, "ConnectedComponents8");
  return cv::connectedComponents(mask, *labels, 8, CV_32S);
}

cv::Mat DiskElement(int radius) {
  RequireRadius(radius, "DiskElement");
  return cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * radius + 1, 2 * radius + 1));
}

void DilateDisk(const cv::Mat& mask, int radius, cv::Mat* out) {
  RequireMask(mask, "DilateDisk");
  RequireRadius(radius, "DilateDisk");
  cv::Mat binary = mask != 0;  // 255 inside
  cv::dilate(binary, *out, DiskElement(radius));
  *out /= 255;
}

void OpenDisk(const cv::Mat& mask, int radius, cv::Mat* out) {
  RequireMask(mask, "OpenDisk");
  RequireRadius(radius, "OpenDisk");
  cv::Mat binary = mask != 0;
  cv::morphologyEx(binary, *out, cv::MORPH_OPEN, DiskElement(radius));
  *out /= 255;
}

void ResizeImage(const cv::Mat& image, int width, int height, ResizeMode mode, cv::Mat* out) {
  RequireImage(image, "ResizeImage");
  Require(width >= 1 && height >= 1, "ResizeImage: the size must be at least 1 x 1; got " +
                                         std::to_string(width) + " x " + std::to_string(height));
  cv::resize(image, *out, cv::Size(width, height), 0, 0,
             mode == ResizeMode::kArea ? cv::INTER_AREA : cv::INTER_LINEAR);
}

void InpaintNavierStokes(const cv::Mat& image, const cv::Mat& mask, double radius_px,
                         cv::Mat* out) {
  RequireImage(image, "InpaintNavierStokes");
  RequireMask(mask, "InpaintNavierStokes");
  Require(mask.size() == image.size(),
          "InpaintNavierStokes: the mask and the image differ in size");
  Require(radius_px > 0 && radius_px <= 1000,
          "InpaintNavierStokes: the radius must be within (0, 1000] px; got " +
              FormatNumber(radius_px));
  cv::inpaint(image, mask, *out, radius_px, cv::INPAINT_NS);
}

}  // namespace qogi
