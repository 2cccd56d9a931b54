#pragma once

// VLAD place descriptor (Jegou et al., "Aggregating local descriptors into a
// compact image representation", CVPR 2010) with intra-normalisation
// (Arandjelovic and Zisserman, "All about VLAD", CVPR 2013) and signed-square-
// root power normalisation (Perronnin et al., ECCV 2010). With 8 clusters of
// 64-D XFeat descriptors, or 4 clusters of 128-D SIFT ones, it is 512-D like
// the MixVPR descriptor of the paper, whose weights are not available.

#include <cstdint>
#include <opencv2/core/mat.hpp>
#include <string>
#include <vector>

#include "common/features/global_descriptor.h"

namespace ag {

/// Cluster centres of VLAD for one local descriptor type.
struct VladCodebook {
  std::string descriptor_type;  ///< local descriptors it was trained on ("xfeat", "sift")
  cv::Mat centers;              ///< clusters x dim, CV_32F
  std::string note;             ///< how it was trained (provenance, free text)

  int clusters() const { return centers.rows; }
  int dim() const { return centers.cols; }
  int vlad_dim() const { return centers.rows * centers.cols; }
};

/// Reads a codebook YAML file (format written by WriteVladCodebook). Throws
/// ag::InputError naming the file on a missing file or malformed content.
VladCodebook ReadVladCodebook(const std::string& path);

/// Parses codebook YAML text; `source` names it in errors.
VladCodebook ParseVladCodebook(const std::string& yaml_text, const std::string& source);

/// Writes `codebook` as YAML (one flow-style row per centre, float precision).
void WriteVladCodebook(const std::string& path, const VladCodebook& codebook);

/// The codebook compiled into the library for `descriptor_type` ("xfeat":
/// 8 x 64, "sift": 4 x 128; from config/features/vlad_<type>.yaml). Throws
/// std::invalid_argument for another type.
VladCodebook BuiltinVladCodebook(const std::string& descriptor_type);

/// k-means (k-means++ seeding, `attempts` restarts, OpenCV's cv::kmeans) over
/// `descriptors` (N x dim CV_32F, N >= clusters). Deterministic for a seed.
VladCodebook TrainVladCodebook(const cv::Mat& descriptors, int clusters,
                               const std::string& descriptor_type, uint64_t seed = 1,
                               int attempts = 3);

/// VLAD of `descriptors` (N x dim CV_32F) over `centers` (K x dim): residuals
/// to the nearest centre summed per cluster, each cluster's sum L2-normalised
/// (intra-normalisation), signed square root, then the K*dim vector
/// L2-normalised. All zeros when there are no descriptors.
std::vector<float> ComputeVlad(const cv::Mat& descriptors, const cv::Mat& centers);

/// GlobalDescriptorExtractor over the frame's local features.
class VladExtractor : public GlobalDescriptorExtractor {
 public:
  explicit VladExtractor(VladCodebook codebook);

  /// Ignores `image`. Throws std::invalid_argument when the features'
  /// descriptor type or length differs from the codebook's.
  std::vector<float> Compute(const cv::Mat& image, const LocalFeatures& features) const override;
  int dim() const override { return codebook_.vlad_dim(); }
  std::string type() const override;

  const VladCodebook& codebook() const { return codebook_; }

 private:
  VladCodebook codebook_;
};

}  // namespace ag
