#pragma once

#include <cstdint>
#include <opencv2/core/mat.hpp>
#include <string>
#include <vector>

namespace ag {

/// Image files (.png, .jpg, .jpeg, .bmp, .pgm, .ppm, .tif, .tiff) directly in
/// `dir`, sorted by name. Throws ag::InputError when `dir` is not a folder.
std::vector<std::string> ListImageFiles(const std::string& dir);

/// Stacks descriptor blocks (each N_i x dim CV_32F) into one matrix, keeping
/// at most `max_rows` rows chosen uniformly at random (seeded, so the same
/// inputs give the same rows).
cv::Mat StackDescriptors(const std::vector<cv::Mat>& blocks, int max_rows, uint64_t seed);

}  // namespace ag
