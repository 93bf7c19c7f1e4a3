#include "robot/dds/convert.h"

#include <Eigen/Geometry>
#include <cmath>
#include <cstring>
#include <opencv2/imgproc.hpp>
#include <sstream>

namespace refgrasp::dds {

namespace {
char* mut(const std::string& s) { return const_cast<char*>(s.c_str()); }
}  // namespace

msg::Time toRosTime(Seconds t) {
  msg::Time r{};
  double sec = std::floor(t);
  long long ns = std::llround((t - sec) * 1e9);
  if (ns >= 1000000000LL) {
    ns -= 1000000000LL;
    sec += 1;
  }
  r.sec = static_cast<int32_t>(sec);
  r.nanosec = static_cast<uint32_t>(ns);
  return r;
}

Seconds fromRosTime(const msg::Time& t) { return t.sec + t.nanosec * 1e-9; }

msg::Duration toRosDuration(Seconds d) {
  const msg::Time t = toRosTime(d);
  msg::Duration r{};
  r.sec = t.sec;
  r.nanosec = t.nanosec;
  return r;
}

Seconds fromRosDuration(const msg::Duration& d) { return d.sec + d.nanosec * 1e-9; }

// ---- images ---------------------------------------------------------------------------------------

const std::vector<std::string>& supportedEncodings() {
  static const std::vector<std::string> e = {"mono8",      "8UC1",        "rgb8",
                                             "bgr8",       "rgba8",       "bgra8",
                                             "bayer_rggb8", "bayer_bggr8", "bayer_gbrg8",
                                             "bayer_grbg8"};
  return e;
}

int bytesPerPixel(const std::string& e) {
  if (e == "mono8" || e == "8UC1" || e.rfind("bayer_", 0) == 0) {
    for (const auto& s : supportedEncodings())
      if (s == e) return 1;
    return 0;
  }
  if (e == "rgb8" || e == "bgr8") return 3;
  if (e == "rgba8" || e == "bgra8") return 4;
  return 0;
}

GrayImage toGray(const msg::Image& m) {
  GrayImage out;
  const std::string enc = m.encoding ? m.encoding : "";
  const int bpp = bytesPerPixel(enc);
  if (bpp == 0) {
    std::string list;
    for (const auto& s : supportedEncodings()) list += (list.empty() ? "" : ", ") + s;
    out.error = "encoding '" + enc + "' not supported (supported: " + list + ")";
    return out;
  }
  if (m.width == 0 || m.height == 0) {
    out.error = "empty image (" + std::to_string(m.width) + "x" + std::to_string(m.height) + ")";
    return out;
  }
  const uint64_t min_step = static_cast<uint64_t>(m.width) * static_cast<uint64_t>(bpp);
  if (m.step < min_step) {
    out.error = "step " + std::to_string(m.step) + " < width " + std::to_string(m.width) + " x " +
                std::to_string(bpp) + " bytes per pixel (" + enc + ")";
    return out;
  }
  const uint64_t need = static_cast<uint64_t>(m.height) * m.step;
  if (m.data._length != need) {
    out.error = "data has " + std::to_string(m.data._length) + " bytes, height " +
                std::to_string(m.height) + " x step " + std::to_string(m.step) + " = " +
                std::to_string(need);
    return out;
  }
  if (m.width > 1u << 15 || m.height > 1u << 15) {
    out.error = "image " + std::to_string(m.width) + "x" + std::to_string(m.height) +
                " larger than 32768 pixels a side";
    return out;
  }
  const int w = static_cast<int>(m.width), h = static_cast<int>(m.height);
  // A header on the message's bytes: no copy.
  const cv::Mat src(h, w, CV_8UC(bpp), m.data._buffer, m.step);
  if (bpp == 1 && enc.rfind("bayer_", 0) != 0) {
    out.gray = src;
    return out;
  }
  int code = 0;
  if (enc == "rgb8") code = cv::COLOR_RGB2GRAY;
  else if (enc == "bgr8") code = cv::COLOR_BGR2GRAY;
  else if (enc == "rgba8") code = cv::COLOR_RGBA2GRAY;
  else if (enc == "bgra8") code = cv::COLOR_BGRA2GRAY;
  // OpenCV names a Bayer pattern by the 2nd and 3rd pixels of its 2nd row (cv_bridge's mapping).
  else if (enc == "bayer_rggb8") code = cv::COLOR_BayerBG2GRAY;
  else if (enc == "bayer_bggr8") code = cv::COLOR_BayerRG2GRAY;
  else if (enc == "bayer_gbrg8") code = cv::COLOR_BayerGR2GRAY;
  else if (enc == "bayer_grbg8") code = cv::COLOR_BayerGB2GRAY;
  if (enc.rfind("bayer_", 0) == 0 && (w < 2 || h < 2)) {
    out.error = "Bayer image " + std::to_string(w) + "x" + std::to_string(h) + " smaller than 2x2";
    return out;
  }
  cv::cvtColor(src, out.gray, code);
  out.copied = true;
  return out;
}

ImageOut::ImageOut(const cv::Mat& image, Seconds stamp, const std::string& frame_id)
    : image_(image.isContinuous() ? image : image.clone()), frame_id_(frame_id) {
  std::memset(&m_, 0, sizeof m_);
  if (image_.type() == CV_8UC3) encoding_ = "bgr8";
  else if (image_.type() == CV_8UC4) encoding_ = "bgra8";
  else encoding_ = "mono8";
  m_.header = makeHeader(stamp, frame_id_);
  m_.height = static_cast<uint32_t>(image_.rows);
  m_.width = static_cast<uint32_t>(image_.cols);
  m_.encoding = mut(encoding_);
  m_.is_bigendian = 0;
  m_.step = static_cast<uint32_t>(image_.step[0]);
  m_.data._buffer = image_.data;
  m_.data._length = m_.data._maximum = static_cast<uint32_t>(image_.step[0] * image_.rows);
  m_.data._release = false;
}

// ---- camera info ----------------------------------------------------------------------------------

std::optional<Intrinsics> toIntrinsics(const msg::CameraInfo& ci, std::string* error) {
  auto fail = [&](const std::string& e) -> std::optional<Intrinsics> {
    if (error) *error = e;
    return std::nullopt;
  };
  if (ci.width == 0 || ci.height == 0 || ci.width > 1u << 15 || ci.height > 1u << 15)
    return fail("camera_info size " + std::to_string(ci.width) + "x" + std::to_string(ci.height) +
                " not usable");
  if (!(ci.k[0] > 0) || !(ci.k[4] > 0)) return fail("camera_info is uncalibrated (K[0] or K[4] <= 0)");
  for (double v : ci.k)
    if (!std::isfinite(v)) return fail("camera_info K has a non-finite value");
  if (ci.binning_x > 1 || ci.binning_y > 1) return fail("camera_info binning not supported");
  if (ci.roi.width != 0 || ci.roi.height != 0 || ci.roi.x_offset != 0 || ci.roi.y_offset != 0) {
    const bool full = ci.roi.x_offset == 0 && ci.roi.y_offset == 0 && ci.roi.width == ci.width &&
                      ci.roi.height == ci.height;
    if (!full) return fail("camera_info region of interest not supported");
  }
  Intrinsics cam;
  cam.width = static_cast<int>(ci.width);
  cam.height = static_cast<int>(ci.height);
  cam.fx = ci.k[0];
  cam.fy = ci.k[4];
  cam.cx = ci.k[2];
  cam.cy = ci.k[5];
  const std::string model = ci.distortion_model ? ci.distortion_model : "";
  const uint32_t nd = ci.d._length;
  for (uint32_t i = 0; i < nd; ++i)
    if (!std::isfinite(ci.d._buffer[i])) return fail("camera_info D has a non-finite value");
  if (model == "plumb_bob" || model == "rational_polynomial" || model.empty() || model == "none") {
    if ((model.empty() || model == "none")) {
      for (uint32_t i = 0; i < nd; ++i)
        if (ci.d._buffer[i] != 0) return fail("camera_info D set without a distortion model");
    } else {
      if (model == "plumb_bob" && nd != 5 && nd != 0)
        return fail("camera_info plumb_bob needs 5 D coefficients, has " + std::to_string(nd));
      if (model == "rational_polynomial") {
        if (nd != 8 && nd != 14 && nd != 0)
          return fail("camera_info rational_polynomial needs 8 D coefficients, has " +
                      std::to_string(nd));
        for (uint32_t i = 5; i < nd; ++i)
          if (ci.d._buffer[i] != 0)
            return fail("camera_info rational_polynomial with k4..k6 != 0 not supported");
      }
      for (uint32_t i = 0; i < nd && i < 5; ++i) cam.dist[i] = ci.d._buffer[i];
    }
  } else {
    return fail("camera_info distortion model '" + model +
                "' not supported (plumb_bob, rational_polynomial with k4..k6 = 0)");
  }
  return cam;
}

CameraInfoOut::CameraInfoOut(const Intrinsics& cam, Seconds stamp, const std::string& frame_id,
                             double baseline_m)
    : frame_id_(frame_id) {
  std::memset(&m_, 0, sizeof m_);
  for (int i = 0; i < 5; ++i) d_[static_cast<size_t>(i)] = cam.dist[static_cast<size_t>(i)];
  m_.header = makeHeader(stamp, frame_id_);
  m_.height = static_cast<uint32_t>(cam.height);
  m_.width = static_cast<uint32_t>(cam.width);
  m_.distortion_model = const_cast<char*>("plumb_bob");
  m_.d._buffer = d_.data();
  m_.d._length = m_.d._maximum = 5;
  m_.d._release = false;
  const double K[9] = {cam.fx, 0, cam.cx, 0, cam.fy, cam.cy, 0, 0, 1};
  const double R[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  const double P[12] = {cam.fx, 0, cam.cx, -cam.fx * baseline_m, 0, cam.fy, cam.cy, 0, 0, 0, 1, 0};
  std::memcpy(m_.k, K, sizeof K);
  std::memcpy(m_.r, R, sizeof R);
  std::memcpy(m_.p, P, sizeof P);
}

// ---- geometry -------------------------------------------------------------------------------------

msg::Pose toRosPose(const Pose& p) {
  Eigen::Quaterniond q(p.R);
  q.normalize();
  if (q.w() < 0) q.coeffs() = -q.coeffs();
  msg::Pose r{};
  r.position = {p.t.x(), p.t.y(), p.t.z()};
  r.orientation = {q.x(), q.y(), q.z(), q.w()};
  return r;
}

Pose fromRosPose(const msg::Pose& p) {
  Eigen::Quaterniond q(p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z);
  Pose r;
  if (q.norm() > 1e-12) r.R = q.normalized().toRotationMatrix();
  r.t = Eigen::Vector3d(p.position.x, p.position.y, p.position.z);
  return r;
}

msg::Vector3 toRosVector(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

msg::Header makeHeader(Seconds stamp, const std::string& frame_id) {
  msg::Header h{};
  h.stamp = toRosTime(stamp);
  h.frame_id = mut(frame_id);
  return h;
}

// ---- joints ---------------------------------------------------------------------------------------

JointStateOut::JointStateOut(Seconds stamp, const std::string& frame_id)
    : frame_id_(frame_id), stamp_(stamp) {
  std::memset(&m_, 0, sizeof m_);
}

void JointStateOut::add(const std::string& name, double position, double velocity, double effort) {
  names_.push_back(name);
  pos_.push_back(position);
  vel_.push_back(velocity);
  eff_.push_back(effort);
}

const msg::JointState& JointStateOut::msg() {
  name_ptrs_.clear();
  for (auto& n : names_) name_ptrs_.push_back(mut(n));
  const auto n = static_cast<uint32_t>(names_.size());
  m_.header = makeHeader(stamp_, frame_id_);
  m_.name = {n, n, name_ptrs_.data(), false};
  m_.position = {n, n, pos_.data(), false};
  m_.velocity = {n, n, vel_.data(), false};
  m_.effort = {n, n, eff_.data(), false};
  return m_;
}

TrajectoryOut::TrajectoryOut(Seconds stamp, const std::vector<std::string>& joints, Kind kind,
                             const std::vector<double>& values, Seconds time_from_start)
    : names_(joints), values_(values) {
  std::memset(&point_, 0, sizeof point_);
  std::memset(&m_, 0, sizeof m_);
  for (auto& n : names_) name_ptrs_.push_back(mut(n));
  const auto nv = static_cast<uint32_t>(values_.size());
  dds_sequence_double seq{nv, nv, values_.data(), false};
  if (kind == Kind::kPositions) point_.positions = seq;
  else point_.velocities = seq;
  point_.time_from_start = toRosDuration(time_from_start);
  m_.header.stamp = toRosTime(stamp);
  m_.header.frame_id = const_cast<char*>("");
  const auto nn = static_cast<uint32_t>(name_ptrs_.size());
  m_.joint_names = {nn, nn, name_ptrs_.data(), false};
  m_.points = {1, 1, &point_, false};
}

int indexOf(const dds_sequence_string& names, const std::string& name) {
  for (uint32_t i = 0; i < names._length; ++i)
    if (names._buffer[i] && name == names._buffer[i]) return static_cast<int>(i);
  return -1;
}

double at(const dds_sequence_double& s, int i, double fallback) {
  return i >= 0 && static_cast<uint32_t>(i) < s._length ? s._buffer[i] : fallback;
}

}  // namespace refgrasp::dds
