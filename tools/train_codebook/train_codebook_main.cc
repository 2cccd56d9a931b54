// train_codebook: k-means VLAD codebook over the local descriptors of a set of
// images (datasets, folders, and/or procedurally generated ones), written as the YAML
// that ag::ReadVladCodebook reads and common/features compiles in.
//
//   train_codebook --procedural 300 --model models/xfeat.onnx -o vlad_xfeat.yaml
//   train_codebook --dataset out/sim_small --every 5 --model models/xfeat.onnx -o vlad_xfeat.yaml
//   train_codebook --images sim_out/air/uav1/images --backend sift -o my_sift.yaml

#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <exception>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "common/dataset/dataset.h"
#include "common/features/feature_extractor.h"
#include "common/features/vlad.h"
#include "common/logging/logging.h"
#include "tools/train_codebook/codebook_training.h"
#include "tools/train_codebook/procedural_images.h"

int main(int argc, char** argv) {
  CLI::App app{"Train a VLAD codebook (k-means over local descriptors) for ag::features"};
  std::string output;
  std::vector<std::string> image_dirs;
  std::vector<std::string> datasets;
  int every = 1;
  int procedural = 0;
  int procedural_width = 640;
  int procedural_height = 480;
  uint64_t seed = 1;
  int clusters = 0;
  int max_descriptors = 200000;
  std::string note;
  ag::FeatureOptions features;
  features.top_k = 512;
  app.add_option("-o,--output", output, "codebook YAML to write")->required();
  app.add_option("--images", image_dirs, "folder of images (repeatable)")
      ->check(CLI::ExistingDirectory);
  app.add_option("--dataset", datasets, "dataset (format v1): every agent's images (repeatable)")
      ->check(CLI::ExistingDirectory);
  app.add_option("--every", every, "use every N-th image of folders and datasets")
      ->check(CLI::PositiveNumber);
  app.add_option("--procedural", procedural, "number of procedurally generated images to add")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--procedural-width", procedural_width, "procedural image width (px)")
      ->check(CLI::PositiveNumber);
  app.add_option("--procedural-height", procedural_height, "procedural image height (px)")
      ->check(CLI::PositiveNumber);
  app.add_option("--seed", seed, "seed of procedural images, subsampling and k-means");
  app.add_option("--clusters", clusters, "clusters (default: 512 / descriptor length)");
  app.add_option("--max-descriptors", max_descriptors, "subsample to at most this many")
      ->check(CLI::PositiveNumber);
  app.add_option("--backend", features.backend, "local features: xfeat or sift")
      ->check(CLI::IsMember({"xfeat", "sift"}));
  app.add_option("--model", features.model_path, "XFeat ONNX model (else $AG_XFEAT_MODEL)");
  app.add_option("--top-k", features.top_k, "keypoints per image")->check(CLI::PositiveNumber);
  app.add_option("--note", note, "provenance note stored in the file (default: generated)");
  CLI11_PARSE(app, argc, argv);
  ag::SetupLogging("train_codebook");

  try {
    if (image_dirs.empty() && datasets.empty() && procedural == 0) {
      throw std::invalid_argument("no images: give --dataset DIR, --images DIR or --procedural N");
    }
    const auto extractor = ag::CreateFeatureExtractor(features);
    if (clusters <= 0) clusters = 512 / extractor->descriptor_dim();

    std::vector<cv::Mat> blocks;
    int images = 0;
    std::vector<std::string> files;
    for (const std::string& dir : image_dirs) {
      const std::vector<std::string> listed = ag::ListImageFiles(dir);
      for (size_t i = 0; i < listed.size(); i += every) files.push_back(listed[i]);
    }
    for (const std::string& dir : datasets) {
      const ag::Dataset dataset = ag::ReadDataset(dir);
      std::vector<const ag::AgentData*> agents = {&dataset.ground};
      for (const auto& [name, air] : dataset.air) agents.push_back(&air);
      for (const ag::AgentData* agent : agents) {
        for (size_t i = 0; i < agent->images.size(); i += every) {
          files.push_back(agent->images[i].path);
        }
      }
    }
    for (const std::string& file : files) {
      const cv::Mat image = cv::imread(file, cv::IMREAD_COLOR);
      if (image.empty()) {
        spdlog::warn("cannot read image '{}', skipped", file);
        continue;
      }
      blocks.push_back(extractor->Extract(image).descriptors);
      ++images;
    }
    for (int i = 0; i < procedural; ++i) {
      const cv::Mat image =
          ag::MakeProceduralImage(cv::Size(procedural_width, procedural_height), seed * 100003 + i);
      blocks.push_back(extractor->Extract(image).descriptors);
      ++images;
    }
    const cv::Mat descriptors = ag::StackDescriptors(blocks, max_descriptors, seed);
    spdlog::info("{} images, {} {} descriptors; k-means with {} clusters", images, descriptors.rows,
                 extractor->type(), clusters);
    ag::VladCodebook codebook =
        ag::TrainVladCodebook(descriptors, clusters, extractor->type(), seed);
    if (note.empty()) {
      note = "k-means (k=" + std::to_string(clusters) + ", seed " + std::to_string(seed) +
             ") over " + std::to_string(descriptors.rows) + " " + extractor->type() +
             " descriptors (top-k " + std::to_string(features.top_k) + ") of " +
             std::to_string(images) + " images:";
      if (procedural > 0) {
        note +=
            " " + std::to_string(procedural) + " procedural (tools/train_codebook --procedural)";
      }
      for (const std::string& dir : image_dirs) note += " folder " + dir;
      for (const std::string& dir : datasets) note += " dataset " + dir;
      if (every > 1) note += " (every " + std::to_string(every) + "th image)";
    }
    codebook.note = note;
    ag::WriteVladCodebook(output, codebook);
    spdlog::info("wrote {} ({} x {}, VLAD dimension {})", output, codebook.clusters(),
                 codebook.dim(), codebook.vlad_dim());
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  return 0;
}
