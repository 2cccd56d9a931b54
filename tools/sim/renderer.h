#pragma once

// Camera image formation by ray casting: every output pixel is unprojected
// through the exact camera model (pinhole-radtan or equidistant), the ray's
// first hit in the world is shaded with the prefiltered albedo, geometric
// edges are supersampled, and the sensor adds exposure, vignetting, optical
// blur, shot and read noise and the gamma curve.

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "common/camera/camera.h"
#include "common/core/error.h"
#include "common/geometry/pose.h"
#include "tools/sim/random.h"
#include "tools/sim/world.h"

namespace ag {

/// One camera: intrinsics, nominal mounting, rate and image formation
/// (scenario key `camera` of an agent).
struct CameraSimOptions {
  std::string model = "pinhole";  ///< pinhole (radtan) or equidistant
  int width = 640;                ///< (px)
  int height = 480;               ///< (px)
  double fx = 500.0, fy = 500.0;  ///< focal lengths (px)
  double cx = 319.5, cy = 239.5;  ///< principal point (px)
  std::vector<double> distortion = {-0.05, 0.012, 0.0004,
                                    -0.0003};  ///< radtan k1 k2 p1 p2 [k3] / equidistant k1..k4
  double rate_hz = 10.0;                       ///< frame rate (Hz)
  std::vector<double> position_m = {0.3, 0.0, 0.2};  ///< nominal position in the body frame (m)
  double pitch_down_deg = 0.0;  ///< nominal tilt below the body's forward axis (deg)
  double yaw_deg = 0.0;         ///< nominal pan to the left of forward (deg)
  double roll_deg = 0.0;        ///< nominal roll about the optical axis (deg)
  double time_offset_s =
      0.0;             ///< nominal t_body = t_camera + offset written to calibration.yaml (s)
  bool color = false;  ///< 8-bit colour (BGR) instead of grey
  bool auto_exposure = true;      ///< scale each frame so its mean reaches exposure_target
  double exposure_target = 0.2;   ///< mean linear brightness auto exposure aims at
  double exposure = 1.0;          ///< extra gain (x)
  double exposure_jitter = 0.03;  ///< per-frame relative gain noise (-)
  double vignetting = 0.25;       ///< relative brightness lost in the corners (-)
  double blur_sigma_px = 0.6;     ///< optical blur, Gaussian sigma (px)
  double read_noise_dn = 0.6;     ///< read noise, linear 8-bit numbers (DN)
  double shot_noise_dn = 0.08;    ///< shot-noise variance per DN of signal (DN)
  double gamma = 2.2;             ///< output encoding gamma
  int max_aniso = 2;              ///< texture samples along the footprint's long axis
  bool supersample_edges = true;  ///< 4 rotated-grid samples on geometric and shadow edges
  bool depth = false;             ///< also write z-depth images (float32 TIFF, m, 0 = sky)

  template <class V>
  void VisitFields(V& v) {
    v("model", model);
    v("width", width);
    v("height", height);
    v("fx", fx);
    v("fy", fy);
    v("cx", cx);
    v("cy", cy);
    v("distortion", distortion);
    v("rate_hz", rate_hz);
    v("position_m", position_m);
    v("pitch_down_deg", pitch_down_deg);
    v("yaw_deg", yaw_deg);
    v("roll_deg", roll_deg);
    v("time_offset_s", time_offset_s);
    v("color", color);
    v("auto_exposure", auto_exposure);
    v("exposure_target", exposure_target);
    v("exposure", exposure);
    v("exposure_jitter", exposure_jitter);
    v("vignetting", vignetting);
    v("blur_sigma_px", blur_sigma_px);
    v("read_noise_dn", read_noise_dn);
    v("shot_noise_dn", shot_noise_dn);
    v("gamma", gamma);
    v("max_aniso", max_aniso);
    v("supersample_edges", supersample_edges);
    v("depth", depth);
  }
  void Check() const;

  CameraParams Params() const;
  /// Nominal T_body_camera: the camera looks along body +x (body: x forward,
  /// y left, z up), then yaw left, pitch down, roll.
  Pose NominalBodyCamera() const;
};

/// Renders images of the world for one camera; thread-safe (const).
class CameraRenderer {
 public:
  explicit CameraRenderer(const CameraSimOptions& options);

  struct Frame {
    cv::Mat image;  ///< CV_8UC1 or CV_8UC3 (BGR)
    cv::Mat depth;  ///< CV_32FC1 z-depth (m) at pixel centres, 0 where the ray sees sky
  };

  /// Renders the view from T_W_camera (camera frame: x right, y down, z
  /// forward). `rng` drives exposure jitter and sensor noise only.
  Frame Render(const SimWorld& world, const Pose& T_W_camera, SimRandom& rng) const;

  /// Exact z-depth of one pixel centre (no image formation), for tests.
  double DepthAt(const SimWorld& world, const Pose& T_W_camera, int u, int v) const;

  const Camera& camera() const { return camera_; }
  const CameraSimOptions& options() const { return options_; }

 private:
  Eigen::Vector3d Bearing(double u, double v) const;
  Eigen::Vector3f Shade(const SimWorld& world, const Eigen::Vector3d& origin,
                        const Eigen::Vector3d& dir_w, double pixel_angle, RayHit* hit, bool* found,
                        bool* shadow, int max_taps = 16) const;

  CameraSimOptions options_;
  Camera camera_;
  std::vector<Eigen::Vector3d> bearings_;  ///< unit rays at pixel centres, row-major
  std::vector<float> pixel_angle_;         ///< angular pixel size (rad)
  std::vector<float> vignette_;            ///< brightness factor per pixel
  static constexpr size_t kGammaLutSize = 1 << 16;
  std::vector<uint8_t> gamma_lut_;  ///< linear [0, 1] -> 8-bit encoded
};

}  // namespace ag
