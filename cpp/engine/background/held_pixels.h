// Image operations of the temporal-percentile background's held pixels
// (where the gas never leaves: the plume's base near its source), which
// the background fills from their gas-free neighbours
// (python/qogi/pipeline/background_choice.py):
//
// * ConnectedComponents8: the 8-connected parts of a mask (the held parts
//   that reach the source);
// * DiskElement, DilateDisk, OpenDisk: a disk's morphology (the margin
//   around the steady core, the seams' thin lines taken out);
// * ResizeImage: area-averaged down, bilinear up (the neighbourhood's
//   median at half resolution);
// * InpaintNavierStokes: Bertalmio, Bertozzi and Sapiro's Navier-Stokes
//   inpainting (CVPR 2001), as OpenCV implements it.
//
// Thin wrappers of OpenCV with their inputs checked, so that the pipeline's
// numerics run in the engine (one OpenCV per process: the Python layer
// would otherwise load opencv-python's own copy, ~20 MB, only for these).
//
// Usage:
//   cv::Mat labels;
//   int n = qogi::ConnectedComponents8(mask, &labels);  // labels 1..n-1
//   cv::Mat filled;
//   qogi::InpaintNavierStokes(residual, mask, 3.0, &filled);
#pragma once

#include <opencv2/core.hpp>

namespace qogi {

// 8-connected components of the nonzero pixels of `mask` (CV_8UC1):
// `labels` CV_32SC1, 0 where the mask is zero, 1..n-1 for the components
// (OpenCV's order: by first pixel in raster order). Returns n.
int ConnectedComponents8(const cv::Mat& mask, cv::Mat* labels);

// A filled disk of `radius` px (>= 0) as a structuring element: CV_8UC1,
// (2 radius + 1) square, OpenCV's ellipse.
cv::Mat DiskElement(int radius);

// `mask` (CV_8UC1) dilated by a disk of `radius` px (0: a copy); 1 inside.
void DilateDisk(const cv::Mat& mask, int radius, cv::Mat* out);

// `mask` (CV_8UC1) opened by a disk of `radius` px: eroded then dilated
// (the parts narrower than the disk removed); 1 inside.
void OpenDisk(const cv::Mat& mask, int radius, cv::Mat* out);

enum class ResizeMode { kArea, kLinear };

// `image` (CV_32FC1) resized to width x height: kArea averages the pixels
// each output pixel covers (for shrinking), kLinear interpolates bilinearly.
void ResizeImage(const cv::Mat& image, int width, int height, ResizeMode mode, cv::Mat* out);

// `image` (CV_32FC1) with the nonzero pixels of `mask` (CV_8UC1, same
// size) filled by Navier-Stokes inpainting from a neighbourhood of
// `radius_px` (> 0). Values of order one and more: scale first (OpenCV's
// inpainting of floats is made for such values).
void InpaintNavierStokes(const cv::Mat& image, const cv::Mat& mask, double radius_px, cv::Mat* out);

}  // namespace qogi
