#include "servo/servo_tasks.h"

#include <visp3/core/vpColVector.h>
#include <visp3/core/vpMatrix.h>
#include <visp3/core/vpVelocityTwistMatrix.h>
#include <visp3/visual_features/vpFeatureDepth.h>
#include <visp3/visual_features/vpFeaturePoint.h>
#include <visp3/visual_features/vpFeatureThetaU.h>
#include <visp3/visual_features/vpFeatureTranslation.h>
#include <visp3/visual_features/vpGenericFeature.h>
#include <visp3/vs/vpAdaptiveGain.h>
#include <visp3/vs/vpServo.h>

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "servo/pose_conversions.h"

namespace refgrasp::servo {

namespace {

bool finitePositive(double x) { return std::isfinite(x) && x > 0; }

vpAdaptiveGain adaptiveGain(const GainOptions& g) {
  if (g.at_zero == g.at_infinity) return vpAdaptiveGain(g.at_zero);
  return vpAdaptiveGain(g.at_zero, g.at_infinity, g.slope_at_zero);
}

vpMatrix toVpMatrix(const Eigen::MatrixXd& m) {
  vpMatrix out(static_cast<unsigned>(m.rows()), static_cast<unsigned>(m.cols()));
  for (Eigen::Index r = 0; r < m.rows(); ++r)
    for (Eigen::Index c = 0; c < m.cols(); ++c)
      out[static_cast<unsigned>(r)][static_cast<unsigned>(c)] = m(r, c);
  return out;
}

// One vpServo set up as ViSP's eye-in-hand examples: v = -lambda (L cVe eJe)^+ e, the
// interaction matrix at the current features (the desired ones move with the estimate).
void setUp(vpServo& task, const GainOptions& gain) {
  task.setServo(vpServo::EYEINHAND_L_cVe_eJe);
  task.setInteractionMatrixType(vpServo::CURRENT, vpServo::PSEUDO_INVERSE);
  task.setLambda(adaptiveGain(gain));
  task.set_cVe(vpVelocityTwistMatrix());  // the controlled frame is the task's own frame
}

}  // namespace

void GainOptions::check(const std::string& what) const {
  refgrasp::check(finitePositive(at_zero), what + ".at_zero", "must be > 0");
  refgrasp::check(finitePositive(at_infinity) && at_infinity <= at_zero, what + ".at_infinity",
                  "must be in (0, at_zero]");
  refgrasp::check(finitePositive(slope_at_zero), what + ".slope_at_zero", "must be > 0");
}

Eigen::Matrix<double, 6, 2> headJacobian(const robot::HeadModel& head, double pan, double tilt) {
  const Pose bMc = robot::headCameraPose(head, pan, tilt);
  const Eigen::Vector3d a_pan = head.bMp.R.col(2);
  const Eigen::Vector3d o_pan = head.bMp.t;
  const Eigen::Vector3d a_tilt =
      head.bMp.R * axisAngle(Eigen::Vector3d::UnitZ(), pan) * Eigen::Vector3d::UnitY();
  const Eigen::Vector3d o_tilt = head.bMp * Eigen::Vector3d(0, 0, head.tilt_height_m);
  const Eigen::Matrix3d cRb = bMc.R.transpose();
  Eigen::Matrix<double, 6, 2> J;
  J.block<3, 1>(0, 0) = cRb * a_pan.cross(bMc.t - o_pan);
  J.block<3, 1>(3, 0) = cRb * a_pan;
  J.block<3, 1>(0, 1) = cRb * a_tilt.cross(bMc.t - o_tilt);
  J.block<3, 1>(3, 1) = cRb * a_tilt;
  return J;
}

Eigen::Matrix<double, 6, Eigen::Dynamic> gripperJacobian(const robot::ArmKinematics& arm,
                                                         const Eigen::VectorXd& q) {
  const int n = arm.dof();
  const Pose bMe = arm.forward(q);
  const Eigen::Matrix3d eRb = bMe.R.transpose();
  const robot::Jacobian bJ = arm.jacobian(q);
  Eigen::Matrix<double, 6, Eigen::Dynamic> J(6, n + 2);
  J.topLeftCorner(3, n) = eRb * bJ.topRows(3);
  J.bottomLeftCorner(3, n) = eRb * bJ.bottomRows(3);
  // Base forward speed: e moves along x_b. Base turn rate about z_b through the base origin.
  J.block<3, 1>(0, n) = eRb * Eigen::Vector3d::UnitX();
  J.block<3, 1>(3, n).setZero();
  J.block<3, 1>(0, n + 1) = eRb * Eigen::Vector3d::UnitZ().cross(bMe.t);
  J.block<3, 1>(3, n + 1) = eRb * Eigen::Vector3d::UnitZ();
  return J;
}

Twist baseTwistAt(const Pose& bMc, double v, double w) {
  const Eigen::Matrix3d cRb = bMc.R.transpose();
  Twist c;
  c.v = cRb * (v * Eigen::Vector3d::UnitX() + w * Eigen::Vector3d::UnitZ().cross(bMc.t));
  c.w = cRb * (w * Eigen::Vector3d::UnitZ());
  return c;
}

// ---- head --------------------------------------------------------------------------------------

void HeadPointingOptions::check() const {
  gain.check("HeadPointingOptions.gain");
  refgrasp::check(finitePositive(max_pan_radps), "HeadPointingOptions.max_pan_radps", "must be > 0");
  refgrasp::check(finitePositive(max_tilt_radps), "HeadPointingOptions.max_tilt_radps",
                  "must be > 0");
  refgrasp::check(finitePositive(tolerance), "HeadPointingOptions.tolerance", "must be > 0");
}

struct HeadPointingTask::Impl {
  vpServo task;
  vpFeaturePoint s, sd;
};

HeadPointingTask::HeadPointingTask(const robot::HeadModel& head, const HeadPointingOptions& o)
    : head_(head), opt_(o), impl_(std::make_unique<Impl>()) {
  opt_.check();
  setUp(impl_->task, opt_.gain);
  impl_->s.buildFrom(0, 0, 1);
  impl_->sd.buildFrom(0, 0, 1);
  impl_->task.addFeature(impl_->s, impl_->sd);
}

HeadPointingTask::~HeadPointingTask() = default;

HeadCommand HeadPointingTask::compute(const Eigen::Vector3d& cP, double pan, double tilt,
                                      const Twist& cV_carrier) {
  HeadCommand out;
  if (!cP.allFinite() || cP.z() < 1e-3) return out;
  const double x = cP.x() / cP.z(), y = cP.y() / cP.z();
  out.error = std::hypot(x, y);
  out.converged = std::abs(x) < opt_.tolerance && std::abs(y) < opt_.tolerance;
  impl_->s.buildFrom(x, y, cP.z());
  impl_->sd.buildFrom(0, 0, cP.z());
  impl_->task.set_cVe(vpVelocityTwistMatrix());
  impl_->task.set_eJe(toVpMatrix(headJacobian(head_, pan, tilt)));
  vpColVector q = impl_->task.computeControlLaw();
  // Feed-forward of the carrier's motion: the feature moves at L cV; cancel it through J^+.
  vpColVector cV(6);
  for (int i = 0; i < 3; ++i) {
    cV[static_cast<unsigned>(i)] = cV_carrier.v[i];
    cV[static_cast<unsigned>(i + 3)] = cV_carrier.w[i];
  }
  q -= impl_->task.getTaskJacobianPseudoInverse() * (impl_->task.getInteractionMatrix() * cV);
  double pan_rate = q[0], tilt_rate = q[1];
  double scale = 1.0;
  if (std::abs(pan_rate) > opt_.max_pan_radps) scale = opt_.max_pan_radps / std::abs(pan_rate);
  if (std::abs(tilt_rate) * scale > opt_.max_tilt_radps)
    scale = opt_.max_tilt_radps / std::abs(tilt_rate);
  out.pan_radps = pan_rate * scale;
  out.tilt_radps = tilt_rate * scale;
  return out;
}

// ---- base --------------------------------------------------------------------------------------

void BaseApproachOptions::check() const {
  turn_gain.check("BaseApproachOptions.turn_gain");
  drive_gain.check("BaseApproachOptions.drive_gain");
  refgrasp::check(finitePositive(max_v_mps), "BaseApproachOptions.max_v_mps", "must be > 0");
  refgrasp::check(finitePositive(max_w_radps), "BaseApproachOptions.max_w_radps", "must be > 0");
  refgrasp::check(finitePositive(turn_in_place_rad) && turn_in_place_rad < M_PI / 2,
                  "BaseApproachOptions.turn_in_place_rad", "must be in (0, pi/2)");
  refgrasp::check(finitePositive(lookahead_m), "BaseApproachOptions.lookahead_m", "must be > 0");
  refgrasp::check(finitePositive(waypoint_m), "BaseApproachOptions.waypoint_m", "must be > 0");
  refgrasp::check(finitePositive(line_tolerance_m), "BaseApproachOptions.line_tolerance_m",
                  "must be > 0");
  refgrasp::check(finitePositive(waypoint_tolerance_m) && waypoint_tolerance_m < waypoint_m,
                  "BaseApproachOptions.waypoint_tolerance_m", "must be in (0, waypoint_m)");
  refgrasp::check(finitePositive(along_tolerance_m), "BaseApproachOptions.along_tolerance_m",
                  "must be > 0");
  refgrasp::check(finitePositive(heading_tolerance_rad), "BaseApproachOptions.heading_tolerance_rad",
                  "must be > 0");
}

// The virtual camera v sits at the base origin looking forward: z_v = x_b, x_v = -y_b, y_v = -z_b.
// The base's (v, w) move it along z_v and turn it about z_b = -y_v. Pioneer's servo couples the
// two features through one 2x2 interaction matrix of ONE point; here the turn follows one point
// (the carrot) and the speed another (Q), so each is its own 1-DOF vpServo: the same law with
// the cross terms (x/Z for v, x for w) left out, which vanish as x -> 0 on the final stretch.
struct BaseApproachTask::Impl {
  vpServo turn, drive;
  vpFeaturePoint x, xd;
  vpFeatureDepth z, zd;
  vpGenericFeature bearing{1};
};

BaseApproachTask::BaseApproachTask(const BaseApproachOptions& o)
    : opt_(o), impl_(std::make_unique<Impl>()) {
  opt_.check();
  Impl& m = *impl_;
  setUp(m.turn, opt_.turn_gain);
  m.x.buildFrom(0, 0, 1);
  m.xd.buildFrom(0, 0, 1);
  m.turn.addFeature(m.x, m.xd, vpFeaturePoint::selectX());
  setUp(m.drive, opt_.drive_gain);
  m.z.buildFrom(0, 0, 1, 0);
  m.zd.buildFrom(0, 0, 1, 0);
  m.drive.addFeature(m.z, m.zd);
}

BaseApproachTask::~BaseApproachTask() = default;

namespace {
vpMatrix baseColumn(int row, double sign) {
  vpMatrix eJe(6, 1);
  eJe[static_cast<unsigned>(row)][0] = sign;
  return eJe;
}
}  // namespace

BaseCommand BaseApproachTask::face(const Eigen::Vector3d& bAim) {
  BaseCommand out;
  Impl& m = *impl_;
  out.bearing_rad = std::atan2(bAim.y(), bAim.x());
  // x = tan(-bearing) in the virtual camera; beyond +-60 deg the servo turns at its cap anyway.
  const double b = std::clamp(out.bearing_rad, -1.05, 1.05);
  m.x.buildFrom(std::tan(-b), 0, 1.0);
  m.xd.buildFrom(0, 0, 1.0);
  m.turn.set_cVe(vpVelocityTwistMatrix());
  m.turn.set_eJe(baseColumn(4, -1.0));  // w: about -y_v
  const vpColVector w = m.turn.computeControlLaw();
  out.w_radps = std::clamp(w[0], -opt_.max_w_radps, opt_.max_w_radps);
  return out;
}

BaseCommand BaseApproachTask::compute(const Eigen::Vector3d& bAim, const Eigen::Vector3d& bDepth,
                                      double depth_desired_m) {
  BaseCommand out = face(bAim);
  Impl& m = *impl_;
  const double Zs = std::max(depth_desired_m, 1e-3);
  out.depth_error_m = bDepth.x() - Zs;
  if (bAim.x() <= 1e-3 || std::abs(out.bearing_rad) > opt_.turn_in_place_rad) return out;
  const double Zd = std::max(bDepth.x(), 1e-3);
  m.z.buildFrom(-bDepth.y() / Zd, 0, Zd, std::log(Zd / Zs));
  m.zd.buildFrom(0, 0, Zs, 0);
  m.drive.set_cVe(vpVelocityTwistMatrix());
  m.drive.set_eJe(baseColumn(2, 1.0));  // v: along z_v
  const vpColVector v = m.drive.computeControlLaw();
  // Slow down while the aimed point is off the axis (none at turn_in_place_rad): the base turns
  // towards its path before it drives along it, without switching.
  const double along = 1.0 - std::abs(out.bearing_rad) / opt_.turn_in_place_rad;
  out.v_mps = std::clamp(v[0], -opt_.max_v_mps, opt_.max_v_mps) * along;
  return out;
}

const char* toString(ApproachStage s) {
  switch (s) {
    case ApproachStage::kToWaypoint: return "to_waypoint";
    case ApproachStage::kFaceLine: return "face_line";
    case ApproachStage::kAlongLine: return "along_line";
    case ApproachStage::kTurn: return "turn";
    case ApproachStage::kDone: return "done";
  }
  return "?";
}

BaseCommand BaseApproachTask::approach(const Pose& wMb, const Pose& wMG,
                                       const std::optional<Eigen::Vector3d>& wObject) {
  const ApproachPoints a = approachPoints(wMb, wMG, opt_.lookahead_m, opt_.waypoint_m);
  if (!stage_) {
    const bool near_line = std::abs(a.lateral_m) <= opt_.line_tolerance_m &&
                           a.along_m <= -opt_.waypoint_m + opt_.waypoint_tolerance_m;
    stage_ = near_line ? ApproachStage::kAlongLine : ApproachStage::kToWaypoint;
  }
  BaseCommand c;
  // Each stage hands over to the next within the same period when it is already done.
  for (int guard = 0; guard < 5; ++guard) {
    switch (*stage_) {
      case ApproachStage::kToWaypoint:
        if (a.bWaypoint.norm() >= opt_.waypoint_tolerance_m) {
          // Pioneer's servo on W itself: its image x, and log(Z / Z*) with Z* half the tolerance.
          // Backing up to W: the same servo in a virtual camera looking backwards (the point
          // mirrored, the speed negated). The way is the one that keeps the object (or Q, on the
          // line beyond G) nearer the base's heading at both ends of the drive, where its bearing
          // is largest (on the straight drive it moves monotonically between them, and the turn
          // at W onto the line brings it ahead): the head, within its pan limits, keeps it in
          // view. W behind the base and the object ahead: it backs up instead of turning its
          // back on the object. Chosen once per drive to W (a tie would flip).
          if (!backwards_to_waypoint_) {
            const Eigen::Vector3d bObject = wObject ? Eigen::Vector3d(wMb.inverse() * *wObject) : a.bDepth;
            const Eigen::Vector2d o = bObject.head<2>(), w = a.bWaypoint.head<2>();
            const double h = std::atan2(w.y(), w.x());  // heading facing W, base frame
            auto worst = [&](double heading) {
              const double at_start = std::remainder(std::atan2(o.y(), o.x()) - heading, 2 * M_PI);
              const Eigen::Vector2d from_w = o - w;
              const double at_w = std::remainder(std::atan2(from_w.y(), from_w.x()) - heading, 2 * M_PI);
              return std::max(std::abs(at_start), std::abs(at_w));
            };
            backwards_to_waypoint_ = worst(h + M_PI) < worst(h);
          }
          const bool behind = *backwards_to_waypoint_;
          const Eigen::Vector3d w = behind ? Eigen::Vector3d(-a.bWaypoint.x(), -a.bWaypoint.y(), 0)
                                           : a.bWaypoint;
          c = compute(w, w, 0.5 * opt_.waypoint_tolerance_m);
          if (behind) c.v_mps = -c.v_mps;
          break;
        }
        stage_ = ApproachStage::kFaceLine;
        continue;
      case ApproachStage::kFaceLine:
        if (std::abs(std::atan2(a.bDepth.y(), a.bDepth.x())) >= opt_.heading_tolerance_rad) {
          c = face(a.bDepth);
          break;
        }
        stage_ = ApproachStage::kAlongLine;
        continue;
      case ApproachStage::kAlongLine:
        if (std::abs(a.along_m) >= opt_.along_tolerance_m) {
          c = compute(a.bAim, a.bDepth, a.depth_desired_m);
          break;
        }
        stage_ = ApproachStage::kTurn;
        continue;
      case ApproachStage::kTurn:
        if (std::abs(a.heading_error_rad) >= opt_.heading_tolerance_rad) {
          c = face(a.bAhead);
          break;
        }
        stage_ = ApproachStage::kDone;
        continue;
      case ApproachStage::kDone:
        c = BaseCommand();
        break;
    }
    break;
  }
  c.stage = *stage_;
  c.points = a;
  return c;
}

// ---- arm ---------------------------------------------------------------------------------------

void ArmAlignOptions::check() const {
  gain.check("ArmAlignOptions.gain");
  refgrasp::check(finitePositive(joint_speed_fraction) && joint_speed_fraction <= 1,
                  "ArmAlignOptions.joint_speed_fraction", "must be in (0, 1]");
  refgrasp::check(finitePositive(max_base_v_mps), "ArmAlignOptions.max_base_v_mps", "must be > 0");
  refgrasp::check(finitePositive(max_base_w_radps), "ArmAlignOptions.max_base_w_radps",
                  "must be > 0");
  refgrasp::check(finitePositive(max_linear_mps), "ArmAlignOptions.max_linear_mps", "must be > 0");
  refgrasp::check(finitePositive(max_angular_radps), "ArmAlignOptions.max_angular_radps",
                  "must be > 0");
  refgrasp::check(std::isfinite(base_weight) && base_weight >= 0 && base_weight <= 10,
                  "ArmAlignOptions.base_weight", "must be in [0, 10]");
  refgrasp::check(finitePositive(joint_limit_rho) && joint_limit_rho <= 0.5,
                  "ArmAlignOptions.joint_limit_rho", "must be in (0, 0.5]");
  refgrasp::check(finitePositive(joint_limit_rho1) && joint_limit_rho1 <= 1,
                  "ArmAlignOptions.joint_limit_rho1", "must be in (0, 1]");
  refgrasp::check(std::isfinite(joint_limit_lambda_tune) && joint_limit_lambda_tune >= 0 &&
                      joint_limit_lambda_tune <= 1,
                  "ArmAlignOptions.joint_limit_lambda_tune", "must be in [0, 1]");
}

struct ArmAlignTask::Impl {
  vpServo task;
  vpFeatureTranslation t{vpFeatureTranslation::cdMc};
  vpFeatureThetaU tu{vpFeatureThetaU::cdRc};
  vpColVector qmin, qmax;
  int n = 0;      ///< columns used: the arm's, plus 2 with the base
  bool base = false;
};

ArmAlignTask::ArmAlignTask(const robot::ArmModel& arm, const ArmAlignOptions& o)
    : kin_(arm), opt_(o), impl_(std::make_unique<Impl>()) {
  opt_.check();
  if (arm.dof() < 1) throw std::invalid_argument("ArmAlignTask: the arm has no joints");
  Impl& m = *impl_;
  m.base = opt_.base_weight > 0;
  m.n = arm.dof() + (m.base ? 2 : 0);
  setUp(m.task, opt_.gain);
  m.t.buildFrom(vpHomogeneousMatrix());
  m.tu.buildFrom(vpHomogeneousMatrix());
  m.task.addFeature(m.t);
  m.task.addFeature(m.tu);
  m.qmin.resize(static_cast<unsigned>(m.n));
  m.qmax.resize(static_cast<unsigned>(m.n));
  for (int i = 0; i < m.n; ++i) {
    const bool joint = i < arm.dof();
    m.qmin[static_cast<unsigned>(i)] = joint ? arm.joints[static_cast<size_t>(i)].limits.min_rad : -1e9;
    m.qmax[static_cast<unsigned>(i)] = joint ? arm.joints[static_cast<size_t>(i)].limits.max_rad : 1e9;
  }
}

ArmAlignTask::~ArmAlignTask() = default;

ArmCommand ArmAlignTask::compute(const Eigen::VectorXd& q, const Pose& bMed, bool base_may_advance) {
  Impl& m = *impl_;
  const int dof = kin_.dof();
  ArmCommand out;
  out.qdot_radps = Eigen::VectorXd::Zero(dof);
  const Pose edMe = bMed.inverse() * kin_.forward(q);
  out.t_m = edMe.t;
  out.theta_u_rad = edMe.rotationVector();

  Eigen::MatrixXd J = gripperJacobian(kin_, q);
  if (!m.base) {
    J.conservativeResize(6, dof);
  } else {
    J.rightCols(2) *= opt_.base_weight;
    // Held at a fixture: the forward column out (a task that wants the base forward leaves the
    // rest to the arm); the command's forward speed is clamped below as well.
    if (!base_may_advance) J.col(dof).setZero();
  }
  const vpHomogeneousMatrix cdMc = toVisp(edMe);
  m.t.buildFrom(cdMc);
  m.tu.buildFrom(cdMc);
  m.task.set_cVe(vpVelocityTwistMatrix());
  m.task.set_eJe(toVpMatrix(J));
  vpColVector u = m.task.computeControlLaw();
  // Marey and Chaumette's avoidance acts on the primary task's joint velocities (as ViSP's
  // examples: q_dot += task.secondaryTaskJointLimitAvoidance(q, q_dot, ...)).
  vpColVector qv(static_cast<unsigned>(m.n));
  for (int i = 0; i < dof; ++i) qv[static_cast<unsigned>(i)] = q[i];
  const vpColVector primary = u;
  if (opt_.joint_limit_avoidance)
    u += m.task.secondaryTaskJointLimitAvoidance(qv, primary, m.qmin, m.qmax, opt_.joint_limit_rho,
                                               opt_.joint_limit_rho1,
                                               opt_.joint_limit_lambda_tune);

  Eigen::VectorXd x(m.n);
  for (int i = 0; i < m.n; ++i) x[i] = u[static_cast<unsigned>(i)];
  // One factor for every limit: joint speeds, base speeds, gripper speed.
  double scale = 1.0;
  auto limit = [&scale](double value, double max) {
    if (std::abs(value) * scale > max) scale = max / std::abs(value);
  };
  for (int i = 0; i < dof; ++i)
    limit(x[i], opt_.joint_speed_fraction *
                    kin_.model().joints[static_cast<size_t>(i)].limits.max_speed_radps);
  if (m.base) {
    limit(x[dof] * opt_.base_weight, opt_.max_base_v_mps);
    limit(x[dof + 1] * opt_.base_weight, opt_.max_base_w_radps);
  }
  const Eigen::Matrix<double, 6, 1> eVe = J * x;
  limit(eVe.head<3>().norm(), opt_.max_linear_mps);
  limit(eVe.tail<3>().norm(), opt_.max_angular_radps);
  x *= scale;
  out.qdot_radps = x.head(dof);
  if (m.base) {
    out.base_v_mps = base_may_advance ? x[dof] * opt_.base_weight : std::min(0.0, x[dof] * opt_.base_weight);
    out.base_w_radps = x[dof + 1] * opt_.base_weight;
  }
  return out;
}

}  // namespace refgrasp::servo
