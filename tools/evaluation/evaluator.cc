#include "tools/evaluation/evaluator.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <fstream>
#include <iomanip>
#include <random>

#include "common/config/options.h"
#include "common/dataset/ground_truth.h"
#include "common/geometry/tum_io.h"
#include "common/pcd/pcd_io.h"
#include "common/wire/channels.h"
#include "common/wire/keyframe_assembler.h"
#include "lcmtypes/checked_decode.h"

namespace ag {
namespace {

constexpr int64_t kSecond = 1000000000LL;

int64_t SecondsToNs(double s) { return static_cast<int64_t>(std::llround(s * 1e9)); }

// A dataset item in the merged timeline. Equal times: odometry first, so a
// sensor sample at the same time can already be posed.
struct TimelineEvent {
  enum Type { kGroundOdometry = 0, kScan = 1, kUgvImage = 2, kAirImage = 3 };
  int64_t t_ns = 0;  // body time
  Type type = kGroundOdometry;
  int agent = 0;     // index into air agents (kAirImage)
  size_t index = 0;  // into the agent's poses / scans / images
  bool operator<(const TimelineEvent& o) const {
    if (t_ns != o.t_ns) return t_ns < o.t_ns;
    if (type != o.type) return type < o.type;
    if (agent != o.agent) return agent < o.agent;
    return index < o.index;
  }
};

struct AirAgentState {
  std::string name;
  const AgentData* data = nullptr;
  std::unique_ptr<AirFrontend> frontend;
  std::unique_ptr<AgentEstimator> estimator;
  std::optional<Pose> truth;
  KeyframeAssembler assembler;  ///< joins split keyframes (frontend.max_part_bytes)
};

}  // namespace

void EvaluateOptions::Check() const {
  CheckOption(ugv_keyframe_period_s > 0, "ugv_keyframe_period_s", "must be > 0");
  CheckOption(window_size >= 1, "window_size", "must be >= 1");
  CheckOption(estimate_period_s > 0, "estimate_period_s", "must be > 0");
  CheckOption(max_duration_s >= 0, "max_duration_s", "must be >= 0");
  CheckOption(link_loss >= 0 && link_loss < 1, "link_loss", "must be in [0, 1)");
}

EvaluationResult Evaluate(const Dataset& dataset, const EvaluateOptions& options,
                          const ProgressFn& progress) {
  CheckOptions(options);
  EvaluationResult result;
  const std::unique_ptr<FeatureExtractor> features = CreateFeatureExtractor(options.features);
  const std::unique_ptr<GlobalDescriptorExtractor> global =
      CreateGlobalDescriptorExtractor(options.global_descriptor, features->type());

  const UgvFrontend ugv(dataset.ground.calibration, features.get(), global.get(), options.ugv);
  OdometryBuffer::Options odom_options;
  odom_options.max_poses = static_cast<int>(dataset.ground.odometry.size()) + 2;
  OdometryBuffer odometry(odom_options);
  VoxelMap map(options.map);
  VoxelMapBuilder builder(&map);
  PlaceDb db(options.place_db);
  const PlaceDbSource source(&db);

  std::vector<AirAgentState> air;
  for (const auto& [name, data] : dataset.air) {
    AirAgentState s;
    s.name = name;
    s.data = &data;
    s.frontend = std::make_unique<AirFrontend>(name, options.air, data.calibration.camera,
                                               features.get(), global.get());
    s.estimator = std::make_unique<AgentEstimator>(name, options.estimator, ugv.camera());
    // The ground learns the UAV camera from camera_info; offline it is the
    // same calibration.
    s.estimator->SetAirCamera(options.air.camera_id,
                              std::make_shared<Camera>(data.calibration.camera.camera));
    if (dataset.groundtruth && dataset.groundtruth->T_wa_wg.count(name)) {
      s.truth = dataset.groundtruth->T_wa_wg.at(name);
    }
    air.push_back(std::move(s));
  }

  // The merged timeline.
  const CameraCalibration& ugv_cam = dataset.ground.calibration.camera;
  const double lidar_offset_s =
      dataset.ground.calibration.lidar ? dataset.ground.calibration.lidar->time_offset_s : 0.0;
  std::vector<TimelineEvent> events;
  for (size_t i = 0; i < dataset.ground.odometry.size(); ++i) {
    events.push_back({dataset.ground.odometry[i].t_ns, TimelineEvent::kGroundOdometry, 0, i});
  }
  for (size_t i = 0; i < dataset.ground.scans.size(); ++i) {
    events.push_back(
        {dataset.ground.scans[i].t_ns + SecondsToNs(lidar_offset_s), TimelineEvent::kScan, 0, i});
  }
  int64_t last_ugv = std::numeric_limits<int64_t>::min();
  for (size_t i = 0; i < dataset.ground.images.size(); ++i) {
    const int64_t t = dataset.ground.images[i].t_ns;
    if (last_ugv != std::numeric_limits<int64_t>::min() &&
        t - last_ugv < SecondsToNs(options.ugv_keyframe_period_s) - kSecond / 1000) {
      continue;
    }
    last_ugv = t;
    events.push_back({t + SecondsToNs(ugv_cam.time_offset_s), TimelineEvent::kUgvImage, 0, i});
  }
  for (size_t a = 0; a < air.size(); ++a) {
    const double offset = air[a].data->calibration.camera.time_offset_s;
    for (size_t i = 0; i < air[a].data->images.size(); ++i) {
      events.push_back({air[a].data->images[i].t_ns + SecondsToNs(offset), TimelineEvent::kAirImage,
                        static_cast<int>(a), i});
    }
  }
  std::sort(events.begin(), events.end());
  if (events.empty()) throw std::runtime_error("dataset " + dataset.dir + " holds no data");
  const int64_t t0 = events.front().t_ns;
  int64_t t_end = events.back().t_ns;
  if (options.max_duration_s > 0) t_end = std::min(t_end, t0 + SecondsToNs(options.max_duration_s));
  result.t0_ns = t0;

  ReportInput report;
  report.dataset = dataset.dir;
  report.config = YamlToJson(OptionsToYaml(options));
  report.has_groundtruth = dataset.groundtruth.has_value();
  for (const auto& s : air) report.agents[s.name];

  UgvWindow window;
  std::deque<TimelineEvent> pending;  // scans and UGV images waiting for odometry
  std::optional<int64_t> last_estimate;
  int64_t ugv_id = 0;

  // The UGV camera's true correction against the LiDAR map: a LiDAR mounting
  // error moves LIO's reported body by T_off (LidarMountOffset), and the
  // camera pose from it is off by C = T_b_c_nominal^-1 T_off^-1 T_b_c_true.
  std::optional<Pose> true_correction;
  if (dataset.groundtruth && dataset.groundtruth->ground_true_camera) {
    true_correction = dataset.ground.calibration.camera.T_body_camera.inverse() *
                      LidarMountOffset(dataset).inverse() *
                      dataset.groundtruth->ground_true_camera->T_body_camera;
  }

  auto run_estimates = [&](int64_t t_ns) {
    for (AirAgentState& s : air) {
      const EstimateResult r = s.estimator->Estimate(t_ns, window, source);
      report.timing.retrieval.push_back(r.timing.retrieval_ms);
      EstimateLog log;
      log.t_ns = t_ns;
      log.success = r.success;
      log.published = r.gate.publish;
      log.reason = r.success ? r.gate.reason : r.reason;
      log.T_wa_wg = r.T_wa_wg;
      log.inliers = r.inliers;
      log.air_seqs = r.air_seqs;
      log.time_ms = r.timing.total_ms;
      log.stage1_ms = r.timing.stage1_ms;
      log.covariance = r.covariance;
      log.has_covariance = r.has_covariance;
      std::optional<Pose> observable;  // the drift-free truth, with ground truth
      if (r.success) {
        report.timing.estimate.push_back(r.timing.total_ms);
        report.timing.stage1.push_back(r.timing.stage1_ms);
        report.timing.stage2.push_back(r.timing.stage2_ms);
        report.timing.matching.push_back(r.timing.matching_ms);
        report.timing.ransac.push_back(r.timing.ransac_ms);
        report.timing.stage1_tracking.push_back(r.timing.stage1_tracking_ms);
        if (s.truth) {
          log.error = FourDofError(r.T_wa_wg, *s.truth);
          observable = ObservableTruth(dataset, *s.data, r.newest_air_t_ns, t_ns, *s.truth);
          if (observable) {
            log.drift_free_error = FourDofError(r.T_wa_wg, *observable);
            Eigen::Vector4d e;
            e.head<3>() = r.T_wa_wg.translation() - observable->translation();
            e[3] = WrapAngle(ProjectedYaw(r.T_wa_wg.linear()) - ProjectedYaw(observable->linear()));
            log.drift_free_residual = e;
            log.truth_drift = FourDofError(*observable, *s.truth);
            const Eigen::Vector3d p = window.back()->T_wg_c.translation();
            log.drift_free_error_at_ugv_m = (r.T_wa_wg * p - *observable * p).norm();
          }
        }
      }
      if (r.gate.publish) {
        report.agents[s.name].fixes.push_back({t_ns, r.T_wa_wg, log.error, log.drift_free_error,
                                               log.drift_free_error_at_ugv_m, log.truth_drift});
      }
      spdlog::debug("estimate {} t={:.1f}: {} {}", s.name, 1e-9 * (t_ns - t0),
                    r.success ? "ok" : "failed", log.reason);
      if (r.success && dataset.groundtruth && dataset.groundtruth->ground_true_camera) {
        // How far stage 1 moved the newest UGV camera towards the truth.
        const CameraCalibration& cam = *dataset.groundtruth->ground_true_camera;
        const InterpolationResult body =
            InterpolateInBuffer(dataset.ground.groundtruth, t_ns + SecondsToNs(cam.time_offset_s));
        if (body.ok()) {
          const Pose truth = body.T * cam.T_body_camera;
          // A camera pose's error: rotation as a vector in the camera frame
          // (x right, y down, z forward; deg; its norm is the angle), to
          // tell a wrong direction from a short one, and translation (m).
          struct CameraError {
            Eigen::Vector3d rotation_deg;
            double translation_m;
          };
          auto err = [&](const Pose& T) {
            const Pose d = truth.inverse() * T;
            const Eigen::AngleAxisd a(d.linear());
            return CameraError{a.axis() * a.angle() * 180 / M_PI, d.translation().norm()};
          };
          if (log.error && observable) {
            const PoseError initial = FourDofError(r.T_wa_wg_initial, *s.truth);
            const PoseError initial_df = FourDofError(r.T_wa_wg_initial, *observable);
            const PoseError single_df = FourDofError(r.T_wa_wg_single, *observable);
            spdlog::debug(
                "  T_wa_wg drift-free error: RANSAC {:.3f} m {:.3f} deg, stage 2 {:.3f} m {:.3f} "
                "deg",
                initial_df.translation_m, initial_df.yaw_deg, single_df.translation_m,
                single_df.yaw_deg);
            // The UAV keyframes span a stretch of the UAV's drift; the
            // truth at the oldest shows how much that stretch matters.
            const std::optional<Pose> at_oldest =
                ObservableTruth(dataset, *s.data, r.oldest_air_t_ns, t_ns, *s.truth);
            if (at_oldest) {
              const PoseError e = FourDofError(r.T_wa_wg_single, *at_oldest);
              const PoseError d = FourDofError(*at_oldest, *observable);
              spdlog::debug(
                  "  UAV keyframes from t={:.1f} to {:.1f}: stage 2 against the truth at the "
                  "oldest {:.3f} m {:.3f} deg; the two truths differ by {:.3f} m {:.3f} deg",
                  1e-9 * (r.oldest_air_t_ns - t0), 1e-9 * (r.newest_air_t_ns - t0), e.translation_m,
                  e.yaw_deg, d.translation_m, d.yaw_deg);
            }
            spdlog::debug(
                "  T_wa_wg error: RANSAC {:.3f} m {:.3f} deg, final {:.3f} m {:.3f} deg, "
                "drift-free {:.3f} m {:.3f} deg (xyz {:+.3f} {:+.3f} {:+.3f}), {} inliers, {} "
                "pairs",
                initial.translation_m, initial.yaw_deg, log.error->translation_m,
                log.error->yaw_deg, log.drift_free_error->translation_m,
                log.drift_free_error->yaw_deg, (*log.drift_free_residual)[0],
                (*log.drift_free_residual)[1], (*log.drift_free_residual)[2], r.inliers, r.pairs);
          }
          {
            // The correction's error against the map.
            const Eigen::AngleAxisd a(s.estimator->camera_correction().linear().transpose() *
                                      true_correction->linear());
            const Eigen::Vector3d v = a.axis() * a.angle() * 180 / M_PI;
            spdlog::debug(
                "  UGV camera correction vs map: {:.3f} deg (camera xyz {:+.2f} {:+.2f} {:+.2f})",
                v.norm(), v.x(), v.y(), v.z());
          }
          const CameraError before = err(r.ugv_T_wg_c_lio);
          const CameraError after = err(r.ugv_T_wg_c_refined);
          const Eigen::Vector3d& v_before = before.rotation_deg;
          const Eigen::Vector3d& v_after = after.rotation_deg;
          spdlog::debug(
              "  UGV camera vs truth: LIO {:.3f} deg {:.3f} m, stage 1 {:.3f} deg {:.3f} m; "
              "rotation error (camera xyz, deg) LIO {:+.2f} {:+.2f} {:+.2f}, stage 1 {:+.2f} "
              "{:+.2f} {:+.2f}",
              v_before.norm(), before.translation_m, v_after.norm(), after.translation_m,
              v_before.x(), v_before.y(), v_before.z(), v_after.x(), v_after.y(), v_after.z());
        }
      }
      result.estimates[s.name].push_back(log);
    }
  };

  // A UAV keyframe as the ground joined it, into the place database.
  std::mt19937_64 link_rng(options.link_loss_seed);
  std::bernoulli_distribution link_loss(options.link_loss);
  auto store = [&](const AirAgentState& s, AgentRecord& rec, KeyframeAssembler::Joined& joined) {
    if (!joined.usable) return;  // no global descriptor arrived
    const int64_t seq = joined.keyframe.seq;
    const int64_t keypoints = static_cast<int64_t>(joined.keyframe.features.size());
    const PlaceDb::InsertResult ins = db.Insert(std::move(joined.keyframe));
    if (!ins.success) {
      spdlog::warn("{}: keyframe {} not stored: {}", s.name, seq, ins.reason);
      return;
    }
    ++rec.keyframes_stored;
    rec.keypoints_stored += keypoints;
  };

  // Handles pending ground items whose pose is now known, in time order.
  auto drain_pending = [&]() {
    while (!pending.empty()) {
      const TimelineEvent e = pending.front();
      if (e.type == TimelineEvent::kScan) {
        const SensorFrame& frame = dataset.ground.scans[e.index];
        PosedScan scan;
        const PoseLookupStatus st = ugv.PoseScan(frame.t_ns, {}, odometry, &scan);
        if (st == PoseLookupStatus::kWait) return;
        pending.pop_front();
        if (st != PoseLookupStatus::kOk) continue;
        scan.points_l = ReadScan(frame.path).points;
        builder.Process(scan);
      } else {
        const SensorFrame& frame = dataset.ground.images[e.index];
        if (ugv.ImageReady(frame.t_ns, odometry) == PoseLookupStatus::kWait) return;
        pending.pop_front();
        const UgvFrontend::Result r = ugv.Process(
            ugv_id++, frame.t_ns, LoadImage(frame, cv::IMREAD_UNCHANGED), odometry, map);
        if (r.status != PoseLookupStatus::kOk) continue;
        report.timing.depth_association_per_keyframe.push_back(r.depth_ms);
        window.push_back(r.keyframe);
        while (static_cast<int>(window.size()) > options.window_size) window.pop_front();
        if (!last_estimate || frame.t_ns - *last_estimate >=
                                  SecondsToNs(options.estimate_period_s) - kSecond / 1000) {
          last_estimate = frame.t_ns;
          run_estimates(frame.t_ns);
        }
      }
    }
  };

  for (const TimelineEvent& e : events) {
    if (e.t_ns > t_end) break;
    switch (e.type) {
      case TimelineEvent::kGroundOdometry:
        odometry.Add(dataset.ground.odometry[e.index]);
        drain_pending();
        break;
      case TimelineEvent::kScan:
      case TimelineEvent::kUgvImage:
        pending.push_back(e);
        drain_pending();
        break;
      case TimelineEvent::kAirImage: {
        AirAgentState& s = air[e.agent];
        const SensorFrame& frame = s.data->images[e.index];
        const InterpolationResult vio = InterpolateInBuffer(s.data->odometry, e.t_ns);
        if (!vio.ok()) break;
        AgentRecord& rec = report.agents[s.name];
        if (s.frontend->CameraInfoDue(frame.t_ns)) {
          const auto info = s.frontend->CameraInfo(frame.t_ns);
          const LinkBytes b =
              LcmLinkBytes(AirCameraInfoChannel(s.name), info.getEncodedSize(), options.air.mtu);
          rec.bytes_sent += b.lcm_udp;
          rec.bytes_ip += b.ip;
          rec.packets.emplace_back(frame.t_ns, b.ip);
        }
        const AirFrontend::Output out = s.frontend->ProcessFrame(
            frame.t_ns, [&] { return LoadImage(frame, cv::IMREAD_UNCHANGED); }, vio.T);
        if (out.features_ms > 0) report.timing.air_features_per_frame.push_back(out.features_ms);
        if (!out.gave_up.empty()) spdlog::debug("{}: {}", s.name, out.gave_up);
        const double t_s = 1e-9 * static_cast<double>(frame.t_ns);
        for (KeyframeAssembler::Joined& joined : s.assembler.Expire(t_s)) store(s, rec, joined);
        if (!out.keyframe) break;
        // Through the wire: encode to bytes, lose IP packets as the link
        // would, decode and join what arrives as the ground would.
        for (const aglcm::air_keyframe_t& packet : out.packets) {
          const LinkBytes b =
              LcmLinkBytes(s.frontend->channel(), packet.getEncodedSize(), options.air.mtu);
          rec.ip_packets += b.ip_packets;
          int64_t lost = 0;
          for (int64_t i = 0; i < b.ip_packets && options.link_loss > 0; ++i) {
            lost += link_loss(link_rng) ? 1 : 0;
          }
          rec.ip_packets_lost += lost;
          if (lost > 0) continue;
          std::vector<uint8_t> bytes(packet.getEncodedSize());
          packet.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
          aglcm::air_keyframe_t received;
          if (DecodeChecked(bytes.data(), static_cast<int>(bytes.size()), &received) < 0) {
            throw std::logic_error("evaluator: own packet does not decode");
          }
          DecodedKeyframe decoded = DecodeKeyframe(received);
          if (!decoded.ok) throw std::logic_error("evaluator: " + decoded.error);
          std::string error;
          for (KeyframeAssembler::Joined& joined :
               s.assembler.Add(std::move(decoded), t_s, &error)) {
            store(s, rec, joined);
          }
          if (!error.empty()) throw std::logic_error("evaluator: " + error);
        }
        ++rec.packets_sent;
        rec.bytes_sent += out.link.lcm_udp;
        rec.bytes_ip += out.link.ip;
        rec.packets.emplace_back(frame.t_ns, out.link.ip);
        if (!rec.first_packet_t_ns) rec.first_packet_t_ns = frame.t_ns;
        break;
      }
    }
    if (progress)
      progress(1e-9 * static_cast<double>(e.t_ns - t0), 1e-9 * static_cast<double>(t_end - t0));
  }
  drain_pending();

  if (true_correction) {
    const Pose& C = *true_correction;
    const auto angle_deg = [](const Eigen::Matrix3d& R) {
      return Eigen::AngleAxisd(R).angle() * 180 / M_PI;
    };
    for (const auto& s : air) {
      const Pose& E = s.estimator->camera_correction();
      report.agents[s.name].ugv_camera_rotation_error_deg =
          std::make_pair(angle_deg(C.linear()), angle_deg(E.linear().transpose() * C.linear()));
      report.agents[s.name].ugv_camera_translation_error_m =
          std::make_pair(C.translation().norm(), (E.inverse() * C).translation().norm());
      report.agents[s.name].ugv_camera_time_offset_ms =
          std::make_pair(1e3 * (dataset.groundtruth->ground_true_camera->time_offset_s -
                                dataset.ground.calibration.camera.time_offset_s),
                         1e3 * s.estimator->camera_time_offset_s());
      // What stage 1 made of the UGV camera's calibration, as the report's
      // ugv_camera_* fields give it, with the centre's error per axis.
      const Eigen::Vector3d centre_cm = 100 * (E.inverse() * C).translation();
      spdlog::info(
          "{}: UGV camera against the map after stage 1: rotation {:.3f} deg off (nominal "
          "{:.3f}), centre ({:+.1f} {:+.1f} {:+.1f}) cm off (camera x right, y down, z ahead), "
          "time offset {:+.1f} ms (true {:+.1f})",
          s.name, report.agents[s.name].ugv_camera_rotation_error_deg->second,
          report.agents[s.name].ugv_camera_rotation_error_deg->first, centre_cm.x(), centre_cm.y(),
          centre_cm.z(), report.agents[s.name].ugv_camera_time_offset_ms->second,
          report.agents[s.name].ugv_camera_time_offset_ms->first);
    }
  }
  result.agents = report.agents;
  result.report = MakeReport(report);
  return result;
}

}  // namespace ag

namespace ag {

void WriteEstimatesCsv(const std::string& path, const std::vector<EstimateLog>& estimates,
                       int64_t t0_ns) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error("cannot write " + path);
  out << "# one row per estimate; t_s from the start of the data; yaw and sd_yaw in deg; "
         "error_* against groundtruth.yaml, drift_free_* against the relation of the two "
         "odometry worlds at the estimate's time (drift_free_at_ugv_m: where it maps the UGV "
         "camera), truth_drift_* between the two truths (empty without ground truth); "
         "time_ms, stage1_ms: the estimate's wall-clock time and stage 1's part of it (camera "
         "rotation calibrator included); air_keyframes: the seq of every UAV keyframe the "
         "estimate used\n";
  out << "t_s,success,published,x,y,z,yaw_deg,sd_x,sd_y,sd_z,sd_yaw_deg,inliers,"
         "error_t_m,error_yaw_deg,drift_free_dx,drift_free_dy,drift_free_dz,"
         "drift_free_dyaw_deg,drift_free_at_ugv_m,truth_drift_m,truth_drift_yaw_deg,time_ms,"
         "stage1_ms,air_keyframes,reason\n";
  out << std::setprecision(9);
  for (const EstimateLog& e : estimates) {
    out << 1e-9 * static_cast<double>(e.t_ns - t0_ns) << ',' << int(e.success) << ','
        << int(e.published);
    if (e.success) {
      out << ',' << e.T_wa_wg.translation().x() << ',' << e.T_wa_wg.translation().y() << ','
          << e.T_wa_wg.translation().z() << ',' << ProjectedYaw(e.T_wa_wg.linear()) * 180 / M_PI;
      for (int i = 0; i < 4; ++i) {
        const double sd = std::sqrt(std::max(0.0, e.covariance(i, i)));
        out << ',' << (i == 3 ? sd * 180 / M_PI : sd);
      }
      out << ',' << e.inliers;
    } else {
      out << ",,,,,,,,,";
    }
    if (e.error) {
      out << ',' << e.error->translation_m << ',' << e.error->yaw_deg;
    } else {
      out << ",,";
    }
    if (e.drift_free_residual) {
      const Eigen::Vector4d& r = *e.drift_free_residual;
      out << ',' << r[0] << ',' << r[1] << ',' << r[2] << ',' << r[3] * 180 / M_PI;
    } else {
      out << ",,,,";
    }
    out << ',';
    if (e.drift_free_error_at_ugv_m) out << *e.drift_free_error_at_ugv_m;
    if (e.truth_drift) {
      out << ',' << e.truth_drift->translation_m << ',' << e.truth_drift->yaw_deg;
    } else {
      out << ",,";
    }
    if (e.success) {
      out << ',' << e.time_ms << ',' << e.stage1_ms;
    } else {
      out << ",,";
    }
    out << ',';
    for (size_t i = 0; i < e.air_seqs.size(); ++i) out << (i ? " " : "") << e.air_seqs[i];
    std::string reason = e.reason;
    std::replace(reason.begin(), reason.end(), ',', ';');
    out << ',' << reason << '\n';
  }
}

void WriteTrajectoryOutputs(const Dataset& dataset, const EvaluationResult& result,
                            const std::string& out_prefix, bool plots) {
  const double t0 = 1e-9 * static_cast<double>(result.t0_ns);
  for (const auto& [name, record] : result.agents) {
    const AgentData& agent = dataset.air.at(name);
    // Mapped UAV trajectory with the fix in force at each VIO time.
    std::vector<StampedPose> mapped;
    size_t fix = 0;
    for (const StampedPose& p : agent.odometry) {
      while (fix + 1 < record.fixes.size() && record.fixes[fix + 1].t_ns <= p.t_ns) ++fix;
      if (record.fixes.empty() || record.fixes[fix].t_ns > p.t_ns) continue;
      mapped.push_back({p.t_ns, record.fixes[fix].T_wa_wg.inverse() * p.T});
    }
    WriteTum(out_prefix + name + "_mapped.tum", mapped,
             "UAV " + name +
                 " body poses mapped into the ground world (T_wg_body) with the "
                 "published T_wa_wg in force; timestamp tx ty tz qx qy qz qw");
    WriteEstimatesCsv(
        out_prefix + name + "_estimates.csv",
        result.estimates.count(name) ? result.estimates.at(name) : std::vector<EstimateLog>{},
        result.t0_ns);
    if (!plots) continue;
    std::vector<PlotSeries> series;
    PlotSeries ugv{"UGV (odometry)", {}, 60, 160, 60};
    for (const auto& p : dataset.ground.odometry)
      ugv.points.emplace_back(p.T.translation().head<2>());
    series.push_back(ugv);
    const auto truth_it = dataset.groundtruth ? dataset.groundtruth->T_wa_wg.find(name)
                                              : std::map<std::string, Pose>::const_iterator();
    if (dataset.groundtruth && truth_it != dataset.groundtruth->T_wa_wg.end() &&
        !agent.groundtruth.empty()) {
      PlotSeries truth{"UAV truth", {}, 80, 80, 80};
      for (const auto& p : agent.groundtruth) {
        truth.points.emplace_back((truth_it->second.inverse() * p.T).translation().head<2>());
      }
      series.push_back(truth);
    }
    PlotSeries est{"UAV mapped with fixes", {}, 200, 90, 30};
    for (const auto& p : mapped) est.points.emplace_back(p.T.translation().head<2>());
    series.push_back(est);
    WritePlot(out_prefix + name + "_trajectory.png", "Trajectories in the ground world: " + name,
              "x (m)", "y (m)", series, true);
    PlotSeries t_err{"translation error (cm)", {}, 200, 90, 30, true};
    PlotSeries y_err{"yaw error (deg)", {}, 40, 40, 200, true};
    for (const auto& f : record.fixes) {
      if (!f.error) continue;
      const double t = 1e-9 * static_cast<double>(f.t_ns) - t0;
      t_err.points.emplace_back(t, 100.0 * f.error->translation_m);
      y_err.points.emplace_back(t, f.error->yaw_deg);
    }
    if (!t_err.points.empty()) {
      WritePlot(out_prefix + name + "_errors.png", "Error of published fixes: " + name, "time (s)",
                "error", {t_err, y_err}, false);
    }
  }
}

}  // namespace ag
