#pragma once

#include <cstdint>
#include <opencv2/core/mat.hpp>

namespace ag {

/// A synthetic BGR image with the structures local features respond to —
/// corners, blobs, edges at all orientations, grids of "windows", text,
/// random textures at several scales — over a smooth random background, then
/// blur, noise and a contrast change. Different seeds give unrelated images;
/// the same seed the same image. Used to train codebooks that owe nothing to
/// a licensed dataset.
cv::Mat MakeProceduralImage(cv::Size size, uint64_t seed);

}  // namespace ag
