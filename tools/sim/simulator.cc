#include "tools/sim/simulator.h"

#include <spdlog/spdlog.h>
#include <time.h>

#include <Eigen/Geometry>
#include <atomic>
#include <chrono>
#include <cmath>
#include <exception>
#include <filesystem>
#include <fstream>
#include <limits>
#include <mutex>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <thread>

#include "common/dataset/dataset.h"
#include "common/pcd/pcd_io.h"
#include "tools/sim/lidar.h"
#include "tools/sim/odometry.h"
#include "tools/sim/random.h"

namespace ag {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

constexpr double kDeg = M_PI / 180.0;

Vector3d RandomUnit(SimRandom& rng) {
  Vector3d v;
  do {
    v = Vector3d(rng.Gaussian(), rng.Gaussian(), rng.Gaussian());
  } while (v.norm() < 1e-6);
  return v.normalized();
}

/// Nominal-to-true extrinsic error: rotation about a random axis by an angle
/// uniform in [min, max], translation in a random direction, uniform length.
Pose RandomPerturbation(SimRandom& rng, const CalibrationErrorOptions& o) {
  Pose delta = Pose::Identity();
  const double angle = rng.Uniform(o.rotation_min_deg, o.rotation_max_deg) * kDeg;
  delta.linear() = Eigen::AngleAxisd(angle, RandomUnit(rng)).toRotationMatrix();
  delta.translation() = rng.Uniform(o.translation_min_m, o.translation_max_m) * RandomUnit(rng);
  return delta;
}

/// `delta` with its rotation angle and translation times `scale` (the
/// same draw, so a scale of 1 changes nothing).
Pose Scaled(const Pose& delta, double scale) {
  if (scale == 1.0) return delta;
  const Eigen::AngleAxisd a(delta.linear());
  Pose out = Pose::Identity();
  out.linear() = Eigen::AngleAxisd(a.angle() * scale, a.axis()).toRotationMatrix();
  out.translation() = scale * delta.translation();
  return out;
}

Pose LidarNominal(const LidarOptions& o) {
  Pose T = Pose::Identity();
  T.linear() = RotZ(o.yaw_deg * kDeg);
  T.translation() = Vector3d(o.position_m[0], o.position_m[1], o.position_m[2]);
  return T;
}

int64_t PeriodNs(double rate_hz) { return std::llround(1e9 / rate_hz); }

/// One unit of parallel work: one image or one scan, writing its own files.
struct Job {
  const SimAgent* agent = nullptr;
  bool scan = false;
  int64_t index = 0;
  int64_t t_ns = 0;  ///< sensor clock stamp
  double tau = 0.0;  ///< true body time of the image / end of the sweep (s)
  std::string path;
  std::string depth_path;
};

void WriteImage(const std::string& path, const cv::Mat& image) {
  // No time or text chunks: OpenCV's PNG writer stores pixels only, so the
  // bytes depend on the pixels alone.
  if (!cv::imwrite(path, image, {cv::IMWRITE_PNG_COMPRESSION, 3})) {
    throw InputError(InputErrorKind::kMissingFile, path, 0, "cannot write image");
  }
}

/// CPU time of the calling thread: per-job cost that other processes on
/// the machine do not distort.
int64_t ThreadCpuMicroseconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1000000 + ts.tv_nsec / 1000;
}

cv::Mat ToBgr(const cv::Mat& image) {
  if (image.channels() == 3) return image;
  cv::Mat bgr;
  cv::cvtColor(image, bgr, cv::COLOR_GRAY2BGR);
  return bgr;
}

}  // namespace

int64_t SimAgent::ClockNs(double tau) const { return clock_start_ns + std::llround(tau * 1e9); }

Pose SimAgent::CameraPoseAtStamp(int64_t t_camera_ns) const {
  return motion->BodyPose(Tau(t_camera_ns) + camera_offset_true_s) * T_body_camera_true;
}

Simulation::~Simulation() = default;

Simulation::Simulation(const Scenario& scenario, uint64_t seed, const std::string& textures_dir)
    : scenario_(scenario), seed_(seed) {
  const ScenarioOptions& so = scenario_.options;
  std::vector<KeepOutPath> keep_out;

  auto ground = std::make_unique<SimAgent>();
  {
    const GroundAgentOptions& g = so.ground;
    ground->name = "ground";
    ground->ground = true;
    ground->motion =
        std::make_unique<AgentMotion>(g.path, false, g.body_height_m, 0.0, g.vibration_deg,
                                      HashCombine(seed, HashString("motion/ground")));
    ground->T_W_world = ProjectTo4Dof(ground->motion->BodyPose(0.0));  // LIO starts at identity
    ground->clock_start_ns = so.start_time_ns;
    ground->camera_options = g.camera;
    ground->renderer = std::make_unique<CameraRenderer>(g.camera);
    SimRandom cal(seed, "calibration/ground");
    ground->T_body_camera_nominal = g.camera.NominalBodyCamera();
    ground->T_body_camera_true =
        ground->T_body_camera_nominal *
        Scaled(RandomPerturbation(cal, g.calibration_error), g.camera_error_scale);
    ground->camera_offset_nominal_s = g.camera.time_offset_s;
    ground->camera_offset_true_s =
        g.camera.time_offset_s + cal.Sign() * cal.Uniform(g.calibration_error.time_offset_min_s,
                                                          g.calibration_error.time_offset_max_s);
    ground->T_body_lidar_nominal = LidarNominal(g.lidar);
    ground->T_body_lidar_true =
        ground->T_body_lidar_nominal *
        Scaled(RandomPerturbation(cal, g.calibration_error), g.lidar_error_scale);
    ground->lidar_offset_s = g.lidar.time_offset_s;
    ground->odometry = g.odometry;
    KeepOutPath k;
    k.points = ground->motion->path().Sample(0.25);
    k.radius_m = so.world.clearance_m + 0.5;  // half the robot's width
    keep_out.push_back(std::move(k));
  }
  agents_.push_back(std::move(ground));
  for (const auto& [name, a] : scenario_.air) {
    auto air = std::make_unique<SimAgent>();
    air->name = name;
    air->motion = std::make_unique<AgentMotion>(
        a.path, true, a.altitude_m, a.altitude_variation_m, a.vibration_deg,
        HashCombine(seed, HashString("motion/air/" + name)));
    SimRandom frame_rng(seed, "world_frame/" + name);
    const Pose offset = MakePose4Dof(frame_rng.Uniform(-1.0, 1.0) * so.air_world_offset_xy_m,
                                     frame_rng.Uniform(-1.0, 1.0) * so.air_world_offset_xy_m,
                                     frame_rng.Uniform(-1.0, 1.0) * so.air_world_offset_z_m,
                                     frame_rng.Uniform(-M_PI, M_PI));
    air->T_W_world = ProjectTo4Dof(air->motion->BodyPose(0.0)) * offset;
    air->clock_start_ns = so.start_time_ns + std::llround(a.clock_offset_s * 1e9);
    air->camera_options = a.camera;
    air->renderer = std::make_unique<CameraRenderer>(a.camera);
    SimRandom cal(seed, "calibration/air/" + name);
    air->T_body_camera_nominal = a.camera.NominalBodyCamera();
    air->T_body_camera_true =
        air->T_body_camera_nominal * RandomPerturbation(cal, a.calibration_error);
    air->camera_offset_nominal_s = a.camera.time_offset_s;
    air->camera_offset_true_s =
        a.camera.time_offset_s + cal.Sign() * cal.Uniform(a.calibration_error.time_offset_min_s,
                                                          a.calibration_error.time_offset_max_s);
    air->odometry = a.odometry;
    KeepOutPath k;
    k.points = air->motion->path().Sample(0.5);
    k.radius_m = so.world.clearance_m + 1.0;
    k.below_z = a.altitude_m - a.altitude_variation_m - 1.5;
    keep_out.push_back(std::move(k));
    agents_.push_back(std::move(air));
  }
  world_ = std::make_unique<SimWorld>(SimWorld::Generate(so.world, seed, keep_out));
  if (!textures_dir.empty()) {
    images_ = std::make_unique<TextureImages>(
        TextureImages::LoadFolder(textures_dir, so.world.texture_texel_m));
    world_->SetTextureImages(images_.get());
  }
}

size_t Simulation::Write(const std::string& out_dir, int threads) const {
  namespace fs = std::filesystem;
  const ScenarioOptions& so = scenario_.options;
  const double duration = so.duration_s;
  const auto start = std::chrono::steady_clock::now();

  DatasetWriter writer(out_dir, so.name,
                       so.description + (so.description.empty() ? "" : " ") +
                           "(simulated by tools/simulate, seed " + std::to_string(seed_) + ")");
  std::vector<Job> jobs;
  for (const auto& agent_ptr : agents_) {
    const SimAgent& agent = *agent_ptr;
    AgentCalibration calibration;
    calibration.camera.camera = agent.camera_options.Params();
    calibration.camera.T_body_camera = agent.T_body_camera_nominal;
    calibration.camera.time_offset_s = agent.camera_offset_nominal_s;
    if (agent.ground) {
      LidarCalibration lidar;
      lidar.T_body_lidar = agent.T_body_lidar_nominal;
      lidar.time_offset_s = agent.lidar_offset_s;
      calibration.lidar = lidar;
      writer.BeginGround(calibration);
    } else {
      writer.BeginAir(agent.name, calibration);
    }
    const std::string agent_dir =
        fs::path(out_dir) / (agent.ground ? "ground" : "air/" + agent.name);
    if (agent.camera_options.depth) fs::create_directories(agent_dir + "/depth");
    // Camera frames: free-running, with a seeded phase against the other
    // sensors; kept when the true exposure time lies within the run.
    const int64_t period = PeriodNs(agent.camera_options.rate_hz);
    SimRandom phase_rng(seed_, "camera_phase/" + agent.name);
    const auto phase = static_cast<int64_t>(phase_rng.Uniform() * static_cast<double>(period));
    for (int64_t k = 0;; ++k) {
      const int64_t t_ns = agent.clock_start_ns + phase + k * period;
      const double tau = agent.Tau(t_ns) + agent.camera_offset_true_s;
      if (tau > duration) break;
      if (tau < 0.0) continue;
      Job job;
      job.agent = &agent;
      job.index = k;
      job.t_ns = t_ns;
      job.tau = tau;
      job.path = writer.AddImage(agent.ground ? "ground" : agent.name, t_ns, ".png");
      if (agent.camera_options.depth)
        job.depth_path = agent_dir + "/depth/" + std::to_string(t_ns) + ".tiff";
      jobs.push_back(job);
    }
    if (agent.ground) {
      const int64_t scan_period = PeriodNs(so.ground.lidar.rate_hz);
      for (int64_t j = 0;; ++j) {
        const int64_t t_ns = agent.clock_start_ns + (j + 1) * scan_period;  // end of sweep j
        const double tau_end = agent.Tau(t_ns) + agent.lidar_offset_s;
        if (tau_end > duration) break;
        if (tau_end - 1.0 / so.ground.lidar.rate_hz < 0.0) continue;
        Job job;
        job.agent = &agent;
        job.scan = true;
        job.index = j;
        job.t_ns = t_ns;
        job.tau = tau_end;
        job.path = writer.AddScan(t_ns);
        jobs.push_back(job);
      }
    }
  }

  // Parallel rendering. Which thread renders a job does not matter: a job's
  // output depends only on the job (its random stream is named by agent and
  // index), so the dataset is identical for any thread count or schedule.
  const int n_threads = threads > 0 ? threads : std::max(1u, std::thread::hardware_concurrency());
  const int previous_cv_threads = cv::getNumThreads();
  cv::setNumThreads(1);  // we parallelise over frames; nested pools only thrash
  std::atomic<size_t> next{0};
  std::atomic<size_t> done{0};
  std::atomic<int64_t> camera_us{0}, lidar_us{0};
  std::mutex error_mutex;
  std::exception_ptr error;
  size_t error_job = std::numeric_limits<size_t>::max();
  auto worker = [&]() {
    while (true) {
      const size_t i = next.fetch_add(1);
      if (i >= jobs.size()) return;
      {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (error) return;
      }
      const int64_t job_start = ThreadCpuMicroseconds();
      try {
        const Job& job = jobs[i];
        const SimAgent& agent = *job.agent;
        if (job.scan) {
          SimRandom rng(seed_, "lidar", static_cast<uint64_t>(job.index));
          const auto T_W_lidar = [&agent](double tau) {
            return agent.motion->BodyPose(tau) * agent.T_body_lidar_true;
          };
          LidarSweep sweep = SimulateLidarSweep(*world_, so.ground.lidar, T_W_lidar, job.tau, rng);
          PointCloud cloud;
          cloud.points = std::move(sweep.points);
          cloud.intensity = std::move(sweep.intensity);
          WriteScan(job.path, cloud, true);
        } else {
          SimRandom rng(seed_, "camera/" + agent.name, static_cast<uint64_t>(job.index));
          const Pose T_W_camera = agent.motion->BodyPose(job.tau) * agent.T_body_camera_true;
          const CameraRenderer::Frame frame = agent.renderer->Render(*world_, T_W_camera, rng);
          WriteImage(job.path, frame.image);
          if (!job.depth_path.empty() && !cv::imwrite(job.depth_path, frame.depth)) {
            throw InputError(InputErrorKind::kMissingFile, job.depth_path, 0,
                             "cannot write depth image");
          }
        }
      } catch (...) {
        std::lock_guard<std::mutex> lock(error_mutex);
        if (i < error_job) {
          error = std::current_exception();
          error_job = i;
        }
        return;
      }
      const int64_t us = ThreadCpuMicroseconds() - job_start;
      (jobs[i].scan ? lidar_us : camera_us).fetch_add(us);
      const size_t n_done = done.fetch_add(1) + 1;
      if (n_done % std::max<size_t>(1, jobs.size() / 10) == 0) {
        spdlog::info("simulate: {}/{} frames and scans", n_done, jobs.size());
      }
    }
  };
  std::vector<std::thread> pool;
  pool.reserve(n_threads);
  for (int t = 0; t < n_threads; ++t) pool.emplace_back(worker);
  for (std::thread& t : pool) t.join();
  cv::setNumThreads(previous_cv_threads);
  if (error) std::rethrow_exception(error);

  // Odometry and ground truth.
  DatasetGroundTruth truth;
  for (const auto& agent_ptr : agents_) {
    const SimAgent& agent = *agent_ptr;
    const int64_t period = PeriodNs(agent.odometry.rate_hz);
    std::vector<StampedPose> gt;
    const Pose T_world_W = agent.T_W_world.inverse();
    for (int64_t k = 0; static_cast<double>(k * period) * 1e-9 <= duration; ++k) {
      StampedPose s;
      s.t_ns = agent.clock_start_ns + k * period;
      s.T = T_world_W * agent.motion->BodyPose(static_cast<double>(k * period) * 1e-9);
      gt.push_back(s);
    }
    SimRandom rng(seed_, "odometry/" + agent.name);
    const std::string key = agent.ground ? "ground" : agent.name;
    // LIO tracks the LiDAR: it reports the body pose that puts the LiDAR,
    // through the nominal extrinsic, where it truly is, so its map is crisp
    // and the LiDAR extrinsic error becomes an offset of the reported body.
    // (T_w_b_lio T_b_l_nominal = T_w_b T_b_l_true.) The camera extrinsic
    // error relative to the LiDAR is what stage 1 has to absorb.
    std::vector<StampedPose> tracked = gt;
    if (agent.ground) {
      const Pose lidar_offset = agent.T_body_lidar_true * agent.T_body_lidar_nominal.inverse();
      for (StampedPose& s : tracked) s.T = s.T * lidar_offset;
    }
    writer.SetOdometry(key, SimulateOdometry(tracked, agent.odometry, rng));
    writer.SetGroundTruthTrajectory(key, gt);
    CameraCalibration true_camera;
    true_camera.camera = agent.camera_options.Params();
    true_camera.T_body_camera = agent.T_body_camera_true;
    true_camera.time_offset_s = agent.camera_offset_true_s;
    if (agent.ground) {
      truth.ground_true_camera = true_camera;
      LidarCalibration lidar;
      lidar.T_body_lidar = agent.T_body_lidar_true;
      lidar.time_offset_s = agent.lidar_offset_s;
      truth.ground_true_lidar = lidar;
    } else {
      truth.air_true_camera[agent.name] = true_camera;
      truth.T_wa_wg[agent.name] = agent.T_W_world.inverse() * ground().T_W_world;
    }
  }
  writer.SetGroundTruth(truth);
  writer.Finish();
  {
    // The effective scenario and seed, so a dataset says how to remake it.
    std::ofstream record(fs::path(out_dir) / "simulation.yaml");
    record << "# tools/simulate record: regenerate with --scenario <this file's scenario> --seed "
           << seed_ << "\n";
    record << "seed: " << seed_ << "\nscenario:\n";
    std::istringstream lines(ScenarioToYaml(scenario_));
    for (std::string line; std::getline(lines, line);) record << "  " << line << "\n";
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  size_t n_scans = 0;
  for (const Job& job : jobs) n_scans += job.scan ? 1 : 0;
  spdlog::info(
      "simulate: wrote {} images and {} scans to {} in {:.1f} s ({} threads; CPU {:.0f} ms per "
      "image, {:.0f} ms per scan)",
      jobs.size() - n_scans, n_scans, out_dir, seconds, n_threads,
      1e-3 * static_cast<double>(camera_us.load()) / std::max<size_t>(1, jobs.size() - n_scans),
      1e-3 * static_cast<double>(lidar_us.load()) / std::max<size_t>(1, n_scans));
  return jobs.size();
}

double Simulation::WritePreview(const std::string& png_path, double tau_s) const {
  const SimAgent& ground_agent = ground();
  const double duration = scenario_.options.duration_s;
  const CameraParams gp = ground_agent.camera_options.Params();
  auto ground_camera = [&](double tau) {
    return ground_agent.motion->BodyPose(tau) * ground_agent.T_body_camera_true;
  };
  // Score an (instant, air agent) pair: where the spot the ground camera
  // looks at (its central ray's hit) lands in the air image; lower is better.
  auto score = [&](double tau, const SimAgent& air) {
    const Pose T_g = ground_camera(tau);
    const Vector3d center_ray = T_g.linear() * ground_agent.renderer->camera().Unproject(
                                                   Vector2d(gp.cx, gp.cy + 0.25 * gp.height));
    RayHit hit;
    if (!world_->Cast(T_g.translation(), center_ray, 40.0, &hit))
      return std::numeric_limits<double>::infinity();
    const Pose T_a = air.motion->BodyPose(tau) * air.T_body_camera_true;
    const Vector3d p_c = T_a.inverse() * hit.p;
    Vector2d uv;
    if (!air.renderer->camera().Project(p_c, &uv) || !air.renderer->camera().InImage(uv, 10.0)) {
      return std::numeric_limits<double>::infinity();
    }
    RayHit air_hit;
    const Vector3d to_point = hit.p - T_a.translation();
    if (world_->Cast(T_a.translation(), to_point.normalized(), to_point.norm() - 0.05, &air_hit)) {
      return std::numeric_limits<double>::infinity();  // occluded from the air
    }
    const CameraParams ap = air.camera_options.Params();
    return std::hypot(uv.x() - ap.cx, uv.y() - ap.cy) / std::hypot(ap.cx, ap.cy);
  };
  const SimAgent* best_air = agents_.size() > 1 ? agents_[1].get() : nullptr;
  if (best_air == nullptr) throw std::logic_error("WritePreview: the scenario has no air agent");
  double best_tau = tau_s >= 0.0 ? std::min(tau_s, duration) : 0.5 * duration;
  double best_score = std::numeric_limits<double>::infinity();
  const double t0 = tau_s >= 0.0 ? best_tau : 0.5;
  const double t1 = tau_s >= 0.0 ? best_tau : duration - 0.5;
  for (double tau = t0; tau <= t1 + 1e-9; tau += 0.5) {
    for (size_t a = 1; a < agents_.size(); ++a) {
      const double s = score(tau, *agents_[a]);
      if (s < best_score) {
        best_score = s;
        best_tau = tau;
        best_air = agents_[a].get();
      }
    }
  }
  SimRandom rng_g(seed_, "preview/ground"), rng_a(seed_, "preview/air");
  const cv::Mat ground_image =
      ToBgr(ground_agent.renderer->Render(*world_, ground_camera(best_tau), rng_g).image);
  cv::Mat air_image =
      ToBgr(best_air->renderer
                ->Render(*world_,
                         best_air->motion->BodyPose(best_tau) * best_air->T_body_camera_true, rng_a)
                .image);
  if (air_image.rows != ground_image.rows) {
    cv::resize(
        air_image, air_image,
        cv::Size(static_cast<int>(std::lround(
                     air_image.cols * static_cast<double>(ground_image.rows) / air_image.rows)),
                 ground_image.rows),
        0, 0, cv::INTER_AREA);
  }
  const cv::Mat gap(ground_image.rows, 8, CV_8UC3, cv::Scalar(255, 255, 255));
  cv::Mat out;
  cv::hconcat(std::vector<cv::Mat>{air_image, gap, ground_image}, out);
  auto label = [&](const std::string& text, int x) {
    cv::putText(out, text, cv::Point(x + 8, 22), cv::FONT_HERSHEY_SIMPLEX, 0.6, cv::Scalar(0, 0, 0),
                3, cv::LINE_AA);
    cv::putText(out, text, cv::Point(x + 8, 22), cv::FONT_HERSHEY_SIMPLEX, 0.6,
                cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
  };
  char when[32];
  std::snprintf(when, sizeof(when), "t = %.1f s", best_tau);
  label("air: " + best_air->name + ", " + when, 0);
  label(std::string("ground, ") + when, air_image.cols + gap.cols);
  WriteImage(png_path, out);
  return best_tau;
}

}  // namespace ag
