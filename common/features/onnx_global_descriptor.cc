#include "common/features/onnx_global_descriptor.h"

#include <cmath>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "common/config/options.h"
#include "common/features/feature_extractor.h"

namespace ag {

OnnxGlobalDescriptor::OnnxGlobalDescriptor(const OnnxGlobalDescriptorOptions& options)
    : options_(options) {
  CheckOptions(options_);
  const std::string what = "global descriptor model '" + options_.model_path + "'";
  std::error_code ec;
  if (!std::filesystem::is_regular_file(options_.model_path, ec)) {
    throw std::runtime_error(what + " does not exist");
  }
  try {
    net_ = cv::dnn::readNetFromONNX(options_.model_path);
  } catch (const cv::Exception& e) {
    throw std::runtime_error("cannot load " + what + ": " + e.what());
  }
  if (net_.empty()) throw std::runtime_error("cannot load " + what + ": empty network");
  std::vector<float> out;
  try {
    out = Run(MakeBlob(
        cv::Mat(options_.input_height, options_.input_width, CV_8UC3, cv::Scalar(128, 128, 128))));
  } catch (const cv::Exception& e) {
    throw std::runtime_error(what + " does not run on a [1,3," +
                             std::to_string(options_.input_height) + "," +
                             std::to_string(options_.input_width) + "] input: " + e.what());
  }
  if (static_cast<int>(out.size()) != options_.output_dim) {
    throw std::runtime_error(what + " gives " + std::to_string(out.size()) +
                             " values, options say output_dim " +
                             std::to_string(options_.output_dim));
  }
}

std::string OnnxGlobalDescriptor::type() const {
  return "onnx:" + std::filesystem::path(options_.model_path).filename().string();
}

cv::Mat OnnxGlobalDescriptor::MakeBlob(const cv::Mat& image) const {
  cv::Mat img = internal::CheckedImage8U(image, "OnnxGlobalDescriptor::Compute");
  if (img.channels() == 1) cv::cvtColor(img, img, cv::COLOR_GRAY2BGR);
  cv::Mat unit;
  img.convertTo(unit, CV_32FC3, 1.0 / 255.0);
  const cv::Size size(options_.input_width, options_.input_height);
  if (unit.size() != size) {
    const bool shrink = size.width < unit.cols && size.height < unit.rows;
    cv::resize(unit, unit, size, 0, 0, shrink ? cv::INTER_AREA : cv::INTER_LINEAR);
  }
  cv::Mat bgr[3];
  cv::split(unit, bgr);
  const int shape[] = {1, 3, size.height, size.width};
  cv::Mat blob(4, shape, CV_32F);
  for (int c = 0; c < 3; ++c) {
    cv::Mat plane(size, CV_32F, blob.ptr<float>() + static_cast<size_t>(c) * size.area());
    const cv::Mat& source = bgr[options_.rgb ? 2 - c : c];
    source.convertTo(plane, CV_32F, 1.0 / options_.stddev[c],
                     -options_.mean[c] / options_.stddev[c]);
  }
  return blob;
}

std::vector<float> OnnxGlobalDescriptor::Run(const cv::Mat& blob) const {
  cv::Mat out;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    net_.setInput(blob, options_.input_name);
    out = net_.forward(options_.output_name).clone();
  }
  out = out.reshape(1, 1);
  std::vector<float> values(out.begin<float>(), out.end<float>());
  double norm2 = 0;
  for (float v : values) norm2 += static_cast<double>(v) * v;
  if (norm2 > 0) {
    const float inv = static_cast<float>(1.0 / std::sqrt(norm2));
    for (float& v : values) v *= inv;
  }
  return values;
}

std::vector<float> OnnxGlobalDescriptor::Compute(const cv::Mat& image,
                                                 const LocalFeatures& /*features*/) const {
  return Run(MakeBlob(image));
}

}  // namespace ag
