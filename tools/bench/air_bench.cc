// air_bench: what the air link costs and what quantisation loses.
// For 128/256/512/1024 keypoints and each descriptor encoding: bytes per
// keyframe packet (LCM message and IP bytes on the link), Mbit/s at 1 Hz,
// and matching precision relative to float32 on image pairs with known
// geometry (real images warped by random homographies); plus extraction
// time per frame of each extractor. Prints tables; asserts nothing.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "common/features/feature_extractor.h"
#include "common/features/letterbox.h"
#include "common/features/xfeat_extractor.h"
#include "common/wire/channels.h"
#include "common/wire/keyframe_codec.h"
#include "common/wire/link_bytes.h"

namespace {

namespace fs = std::filesystem;
using ag::ArrayEncoding;

struct Pair {
  cv::Mat a, b;
  cv::Mat H;  // maps pixels of a into b
};

// A random homography that keeps most of the image in view.
cv::Mat RandomHomography(const cv::Size& size, std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<cv::Point2f> src = {{0, 0},
                                  {static_cast<float>(size.width), 0},
                                  {static_cast<float>(size.width), static_cast<float>(size.height)},
                                  {0, static_cast<float>(size.height)}};
  std::vector<cv::Point2f> dst;
  dst.reserve(src.size());
  const double jitter = 0.12 * std::min(size.width, size.height);
  for (const auto& p : src) dst.emplace_back(p.x + jitter * u(rng), p.y + jitter * u(rng));
  return cv::getPerspectiveTransform(src, dst);
}

// Fraction of mutual-NN + ratio matches whose keypoint in b lies within
// 3 px of where H maps the keypoint of a, and their number.
std::pair<double, int> Precision(const ag::LocalFeatures& a, const cv::Mat& a_desc,
                                 const ag::LocalFeatures& b, const cv::Mat& H) {
  cv::BFMatcher matcher(cv::NORM_L2, true);
  std::vector<cv::DMatch> matches;
  matcher.match(a_desc, b.descriptors, matches);
  int correct = 0;
  for (const auto& m : matches) {
    const cv::Mat p =
        (cv::Mat_<double>(3, 1) << a.keypoints[m.queryIdx].x(), a.keypoints[m.queryIdx].y(), 1.0);
    const cv::Mat q = H * p;
    const double dx = q.at<double>(0) / q.at<double>(2) - b.keypoints[m.trainIdx].x();
    const double dy = q.at<double>(1) / q.at<double>(2) - b.keypoints[m.trainIdx].y();
    correct += dx * dx + dy * dy <= 9.0;
  }
  return {matches.empty() ? 0.0 : static_cast<double>(correct) / matches.size(), correct};
}

double MedianMs(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "air_bench: packet bytes, Mbps at 1 Hz, quantised matching precision, extraction time"};
  std::string images_dir =
      "../shared/data/kitti_raw_2011_09_26_drive_0001_mini/2011_09_26/"
      "2011_09_26_drive_0001_sync/image_02/data";
  std::string model;
  int warps = 3;
  app.add_option("--images", images_dir, "folder of real images (PNG/JPEG) to warp");
  app.add_option("--model", model, "XFeat ONNX model (else $AG_XFEAT_MODEL; absent: SIFT only)");
  app.add_option("--warps", warps, "homography warps per image");
  CLI11_PARSE(app, argc, argv);

  std::vector<cv::Mat> images;
  if (fs::is_directory(images_dir)) {
    std::vector<fs::path> files;
    for (const auto& e : fs::directory_iterator(images_dir)) files.push_back(e.path());
    std::sort(files.begin(), files.end());
    for (const auto& f : files) {
      cv::Mat img = cv::imread(f.string(), cv::IMREAD_GRAYSCALE);
      if (!img.empty()) images.push_back(img);
    }
  }
  if (images.empty()) {
    std::fprintf(stderr, "air_bench: no images in %s (use --images)\n", images_dir.c_str());
    return 2;
  }
  std::mt19937 rng(1);
  std::vector<Pair> pairs;
  for (const cv::Mat& img : images) {
    for (int w = 0; w < warps; ++w) {
      Pair p;
      p.a = img;
      p.H = RandomHomography(img.size(), rng);
      cv::warpPerspective(img, p.b, p.H, img.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT);
      pairs.push_back(p);
    }
  }

  std::printf(
      "Air keyframe packet size (64-D descriptors, 512-D global descriptor float16, agent "
      "'uav0')\n");
  std::printf(
      "| keypoints | encoding | LCM message (B) | on the link, IPv4 (B) | Mbps at 1 Hz | paper "
      "(float32) Mbps |\n");
  std::printf("|---|---|---|---|---|---|\n");
  const std::vector<int> counts = {128, 256, 512, 1024};
  const std::vector<ArrayEncoding> encodings = {ArrayEncoding::kFloat32, ArrayEncoding::kFloat16,
                                                ArrayEncoding::kInt8, ArrayEncoding::kBits4};
  for (int n : counts) {
    for (ArrayEncoding e : encodings) {
      ag::PacketFormat f;
      f.descriptors = e;
      f.global = ArrayEncoding::kFloat16;
      const int64_t size = ag::EncodedKeyframeSize("uav0", "cam0", "xfeat", n, 64, 512, f);
      const ag::LinkBytes link = ag::LcmLinkBytes(ag::AirKeyframeChannel("uav0"), size);
      const double paper = 4.0 * (2 * n + 64 * n + 7 + 512) * 8 / 1e6;
      std::printf("| %d | %s | %lld | %lld | %.3f | %.2f |\n", n, ag::ToString(e),
                  static_cast<long long>(size), static_cast<long long>(link.ip),
                  link.ip * 8.0 / 1e6, paper);
    }
  }

  // Whole keyframes versus parts of one IP packet (frontend.max_part_bytes:
  // 1500) on a link that loses IP packets independently with probability p.
  std::printf(
      "\nLossy link: keyframe sent whole vs split into parts of <= 1500 IPv4 bytes (int8 "
      "descriptors); expected keypoints that arrive, and keyframes still usable (a whole one "
      "needs every IP packet, a split one its first or last part)\n");
  std::printf(
      "| keypoints | whole: IPv4 B | IP packets | split: IPv4 B | parts | extra bytes | loss | "
      "whole: keypoints arriving | split: keypoints arriving | whole: keyframes usable | "
      "split: keyframes usable |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (int n : {256, 512, 1024}) {
    ag::PacketFormat f;
    f.descriptors = ArrayEncoding::kInt8;
    f.global = ArrayEncoding::kFloat16;
    const std::string channel = ag::AirKeyframeChannel("uav0");
    const ag::LinkBytes whole =
        ag::LcmLinkBytes(channel, ag::EncodedKeyframeSize("uav0", "cam0", "xfeat", n, 64, 512, f));
    const ag::PartCapacity cap = ag::FitPartCapacity(
        "uav0", "cam0", "xfeat", 64, 512, f, n,
        [&](int64_t size) { return ag::LcmLinkBytes(channel, size).ip <= 1500; });
    int64_t split_ip = 0;
    const std::vector<int64_t> parts =
        ag::EncodedPartSizes("uav0", "cam0", "xfeat", n, 64, 512, f, cap);
    for (int64_t size : parts) split_ip += ag::LcmLinkBytes(channel, size).ip;
    const int64_t ip_packets = whole.ip_packets;
    for (double loss : {0.01, 0.05, 0.1, 0.2}) {
      const double whole_arrives = std::pow(1 - loss, static_cast<double>(ip_packets));
      const double usable = parts.size() > 1 ? 1 - loss * loss : 1 - loss;
      std::printf(
          "| %d | %lld | %lld | %lld | %zu | %.1f%% | %.0f%% | %.0f | %.0f | %.0f%% | %.0f%% |\n",
          n, static_cast<long long>(whole.ip), static_cast<long long>(ip_packets),
          static_cast<long long>(split_ip), parts.size(),
          100.0 * static_cast<double>(split_ip - whole.ip) / static_cast<double>(whole.ip),
          100 * loss, n * whole_arrives, n * (1 - loss) * usable, 100 * whole_arrives,
          100 * usable);
    }
  }

  for (const std::string backend : {"xfeat", "sift"}) {
    ag::FeatureOptions fo;
    fo.backend = backend;
    fo.model_path = model;
    if (backend == "xfeat" && ag::ResolveXFeatModelPath(model).empty()) {
      std::printf("\n(%s skipped: no model; pass --model or set AG_XFEAT_MODEL)\n",
                  backend.c_str());
      continue;
    }
    std::printf(
        "\nMatching precision of quantised descriptors vs float32, %s, %zu pairs (%zu real images "
        "x %d homographies), "
        "3 px, mutual nearest neighbour\n",
        backend.c_str(), pairs.size(), images.size(), warps);
    std::printf(
        "| keypoints | extraction ms (median) | float32 precision | encoding | precision | "
        "relative to float32 | correct matches relative |\n");
    std::printf("|---|---|---|---|---|---|---|\n");
    for (int n : counts) {
      fo.top_k = n;
      const auto extractor = ag::CreateFeatureExtractor(fo);
      if (extractor->type() != backend) break;  // fell back
      std::vector<double> times;
      std::vector<ag::LocalFeatures> fa, fb;
      for (const Pair& p : pairs) {
        const auto t0 = std::chrono::steady_clock::now();
        fa.push_back(extractor->Extract(p.a));
        times.push_back(
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                .count());
        fb.push_back(extractor->Extract(p.b));
      }
      double base_prec = 0;
      int base_correct = 0;
      for (ArrayEncoding e : encodings) {
        double prec_sum = 0;
        int correct = 0;
        for (size_t i = 0; i < pairs.size(); ++i) {
          cv::Mat desc;
          std::string error;
          ag::DequantizeArray(ag::QuantizeArray(fa[i].descriptors, e), &desc, &error);
          for (int r = 0; r < desc.rows; ++r) {
            cv::Mat row = desc.row(r);
            cv::normalize(row, row);
          }
          const auto [p, c] = Precision(fa[i], desc, fb[i], pairs[i].H);
          prec_sum += p;
          correct += c;
        }
        const double prec = prec_sum / pairs.size();
        if (e == ArrayEncoding::kFloat32) {
          base_prec = prec;
          base_correct = correct;
        }
        std::printf("| %d | %.1f | %.4f | %s | %.4f | %.4f | %.4f |\n", n, MedianMs(times),
                    base_prec, ag::ToString(e), prec, base_prec > 0 ? prec / base_prec : 0.0,
                    base_correct > 0 ? static_cast<double>(correct) / base_correct : 0.0);
      }
    }
  }
  // What native resolution costs: XFeat's input is 640x640, so a larger
  // image is either shrunk into one input or cut into tiles
  // (features.max_tiles), one network pass each.
  if (!ag::ResolveXFeatModelPath(model).empty()) {
    std::printf(
        "\nXFeat extraction by image size and features.max_tiles (the real images resized; "
        "1024 keypoints; median over %zu images)\n",
        images.size());
    std::printf("| image | max_tiles | network passes | scale | extraction ms (median) |\n");
    std::printf("|---|---|---|---|---|\n");
    for (const cv::Size size : {images[0].size(), cv::Size(1280, 720), cv::Size(1920, 1080)}) {
      for (int max_tiles : {1, 2, 6}) {
        ag::FeatureOptions fo;
        fo.model_path = model;
        fo.max_tiles = max_tiles;
        const auto extractor = ag::CreateFeatureExtractor(fo);
        const ag::TileLayout layout = ag::ComputeTileLayout(
            size, {ag::XFeatExtractor::kInputSize, ag::XFeatExtractor::kInputSize}, max_tiles,
            ag::XFeatExtractor::kTileOverlap);
        std::vector<double> times;
        for (const cv::Mat& img : images) {
          cv::Mat resized;
          cv::resize(img, resized, size, 0, 0, cv::INTER_LINEAR);
          const auto t0 = std::chrono::steady_clock::now();
          extractor->Extract(resized);
          times.push_back(
              std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                  .count());
        }
        std::printf("| %dx%d | %d | %zu | %.3f | %.1f |\n", size.width, size.height, max_tiles,
                    layout.tiles.size(), layout.scaled.scale_x, MedianMs(times));
      }
    }
  }
  return 0;
}
