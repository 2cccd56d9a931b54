#pragma once

#include <string>
#include <vector>

namespace ag {

/// Intrinsic calibration of one camera, as in a dataset's calibration.yaml
/// and in the camera_info LCM message.
struct CameraParams {
  /// "pinhole" (pinhole with radial-tangential distortion, OpenCV's model)
  /// or "equidistant" (Kannala-Brandt fisheye, OpenCV's cv::fisheye model).
  std::string model = "pinhole";
  int width = 0;                          ///< image width (px)
  int height = 0;                         ///< image height (px)
  double fx = 0, fy = 0, cx = 0, cy = 0;  ///< focal lengths and principal point (px)
  /// radtan: [k1, k2, p1, p2] or [k1, k2, p1, p2, k3]; equidistant:
  /// [k1, k2, k3, k4]; empty means no distortion.
  std::vector<double> distortion;
};

}  // namespace ag
