#include "tools/train_codebook/codebook_training.h"

#include <algorithm>
#include <filesystem>
#include <numeric>
#include <opencv2/core.hpp>
#include <stdexcept>

#include "common/core/error.h"

namespace ag {

std::vector<std::string> ListImageFiles(const std::string& dir) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) {
    throw InputError(InputErrorKind::kMissingFile, dir, 0, "not a folder of images");
  }
  std::vector<std::string> files;
  for (const fs::directory_entry& entry : fs::directory_iterator(dir)) {
    if (!entry.is_regular_file()) continue;
    std::string ext = entry.path().extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
    for (const char* known : {".png", ".jpg", ".jpeg", ".bmp", ".pgm", ".ppm", ".tif", ".tiff"}) {
      if (ext == known) files.push_back(entry.path().string());
    }
  }
  std::sort(files.begin(), files.end());
  return files;
}

cv::Mat StackDescriptors(const std::vector<cv::Mat>& blocks, int max_rows, uint64_t seed) {
  cv::Mat all;
  for (const cv::Mat& block : blocks) {
    if (block.empty()) continue;
    if (!all.empty() && (block.cols != all.cols || block.type() != all.type())) {
      throw std::invalid_argument("StackDescriptors: blocks differ in length or type");
    }
    all.push_back(block);
  }
  if (all.rows <= max_rows) return all;
  std::vector<int> rows(all.rows);
  std::iota(rows.begin(), rows.end(), 0);
  cv::RNG rng(seed);
  for (int i = static_cast<int>(rows.size()) - 1; i > 0; --i) {  // Fisher-Yates
    std::swap(rows[i], rows[rng.uniform(0, i + 1)]);
  }
  rows.resize(max_rows);
  std::sort(rows.begin(), rows.end());
  cv::Mat subset(max_rows, all.cols, all.type());
  for (int i = 0; i < max_rows; ++i) all.row(rows[i]).copyTo(subset.row(i));
  return subset;
}

}  // namespace ag
