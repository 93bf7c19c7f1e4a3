#include "component/vision_component.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <map>
#include <mutex>
#include <thread>

#include "component/latest_slot.h"
#include "component/rate_limited_log.h"
#include "core/error.h"
#include "robot/dds/convert.h"
#include "robot/dds/service.h"
#include "robot/dds/transport.h"

namespace refgrasp::component {

namespace msg = dds::msg;
using dds::Sample;

void VisionComponentOptions::check() const {
  dds::checkDomainAndNamespace(domain, ns, "VisionComponentOptions");
  if (track) tracking.check();
  refgrasp::check(std::isfinite(warning_period_s) && warning_period_s >= 0,
                  "VisionComponentOptions.warning_period_s", "must be >= 0");
}

namespace {

double steadyNow() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

using ImagePtr = std::shared_ptr<Sample<msg::Image>>;
using InfoPtr = std::shared_ptr<Sample<msg::CameraInfo>>;

int64_t stampNs(const msg::Header& h) {
  return static_cast<int64_t>(h.stamp.sec) * 1000000000LL + h.stamp.nanosec;
}
std::string frameOf(const msg::Header& h) { return h.frame_id ? h.frame_id : ""; }

/// One camera: its topics, readers and the newest camera_info.
struct Eye {
  std::string image_topic, info_topic;  // ROS names
  std::unique_ptr<dds::Reader<msg::Image>> image;
  std::unique_ptr<dds::Reader<msg::CameraInfo>> info;
  InfoPtr latest_info;
  std::map<int64_t, ImagePtr> waiting;  // stereo: images by stamp until their partner comes
};

/// A frame for the detector: the samples stay alive (mono8 pixels are used in place).
struct Job {
  long seq = 0;
  ImagePtr image[2];
  InfoPtr info[2];
  double received_at = 0;  // steady clock: taken from DDS
  double queued_at = 0;    // put into the slot
};

/// The newest answer for one object.
struct Result {
  bool have = false;  // any frame processed yet
  bool found = false;
  Pose cMo;
  std::string error;
};

double median(std::deque<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

using Server = dds::ServiceServer<msg::DetectRequest, msg::DetectResponse>;

}  // namespace

struct VisionComponent::Impl {
  Impl(detector::Detector d, const VisionComponentOptions& o, WarningSink w)
      : det(std::move(d)),
        opt(o),
        log(w ? std::move(w) : [](const std::string& s) { std::fprintf(stderr, "%s\n", s.c_str()); },
            o.warning_period_s),
        pp(o.domain),
        ws(pp) {
    for (int i = 0; i < det.objectCount(); ++i) {
      if (!det.object(i).has3d())
        throw std::invalid_argument(det.object(i).name + ": the component needs a reference_pose (3D)");
      names.push_back(det.object(i).name);
    }
    if (names.empty()) throw std::invalid_argument("the component needs at least one object");
    if (o.track) pipeline = std::make_unique<servo::TargetTracker>(det, o.tracking);
    results.resize(names.size());
    const bool stereo = o.stereo.has_value();
    eyes.resize(stereo ? 2 : 1);
    for (size_t e = 0; e < eyes.size(); ++e) {
      const std::string base = stereo ? dds::joinRosName(o.ns, e == 0 ? "left" : "right") : o.ns;
      eyes[e].image_topic = dds::joinRosName(base, "image_raw");
      eyes[e].info_topic = dds::joinRosName(base, "camera_info");
      eyes[e].image = std::make_unique<dds::Reader<msg::Image>>(
          pp, dds::ddsTopicName(eyes[e].image_topic), dds::QosProfile::sensorData());
      eyes[e].info = std::make_unique<dds::Reader<msg::CameraInfo>>(
          pp, dds::ddsTopicName(eyes[e].info_topic), dds::QosProfile::sensorData());
      ws.attach(eyes[e].image->condition(), 1 + static_cast<intptr_t>(e));
      ws.attach(eyes[e].info->condition(), 3 + static_cast<intptr_t>(e));
    }
    const dds::QosProfile out = dds::QosProfile::reliable(10);
    pose_w = std::make_unique<dds::Writer<msg::PoseStamped>>(
        pp, dds::ddsTopicName(dds::joinRosName(o.ns, "object_pose")), out);
    det_w = std::make_unique<dds::Writer<msg::Detection3DArray>>(
        pp, dds::ddsTopicName(dds::joinRosName(o.ns, "detections")), out);
    info_w = std::make_unique<dds::Writer<msg::ObjectInfo>>(
        pp, dds::ddsTopicName(dds::joinRosName(o.ns, "object_info")),
        dds::QosProfile::reliable(std::max(10, static_cast<int>(names.size()) * 2)));
    server = std::make_unique<Server>(pp, dds::joinRosName(o.ns, "detect"));
    ws.attach(server->requestCondition(), 5);
    rx = std::thread([this] { rxLoop(); });
    worker = std::thread([this] { workLoop(); });
  }

  void stop() {
    if (stopping.exchange(true)) return;
    ws.wake();
    slot.close();
    if (rx.joinable()) rx.join();
    if (worker.joinable()) worker.join();
  }

  // ---- receive thread -----------------------------------------------------------------------

  void rxLoop() {
    while (!stopping) {
      double timeout = 0.2;
      {
        std::lock_guard<std::mutex> lock(mu);
        for (const auto& p : pending) timeout = std::min(timeout, std::max(0.0, p.deadline - steadyNow()));
      }
      ws.wait(timeout);
      if (stopping) break;
      for (auto& e : eyes) {
        Sample<msg::CameraInfo> ci;
        if (e.info->takeNewest(&ci) > 0) e.latest_info = std::make_shared<Sample<msg::CameraInfo>>(std::move(ci));
      }
      if (eyes.size() == 1) takeMono();
      else takeStereo();
      takeRequests();
      expirePending();
    }
  }

  void enqueue(Job job) {
    job.queued_at = steadyNow();
    std::lock_guard<std::mutex> lock(stats_mu);
    job.seq = ++st.received;
    if (slot.put(std::move(job))) ++st.dropped;
  }

  void takeMono() {
    std::vector<Sample<msg::Image>> all = eyes[0].image->takeAll();
    if (all.empty()) return;
    {
      // Only the newest reaches the detector; the others are dropped now.
      std::lock_guard<std::mutex> lock(stats_mu);
      st.received += static_cast<long>(all.size()) - 1;
      st.dropped += static_cast<long>(all.size()) - 1;
    }
    Job j;
    j.received_at = steadyNow();
    j.image[0] = std::make_shared<Sample<msg::Image>>(std::move(all.back()));
    j.info[0] = eyes[0].latest_info;
    enqueue(std::move(j));
  }

  void takeStereo() {
    for (auto& e : eyes)
      for (auto& s : e.image->takeAll()) {
        const int64_t t = stampNs(s->header);
        e.waiting[t] = std::make_shared<Sample<msg::Image>>(std::move(s));
      }
    // The newest stamp both eyes have; everything older on either side will never pair.
    int64_t best = INT64_MIN;
    for (const auto& [t, img] : eyes[0].waiting)
      if (eyes[1].waiting.count(t)) best = std::max(best, t);
    if (best != INT64_MIN) {
      Job j;
      j.received_at = steadyNow();
      for (size_t e = 0; e < 2; ++e) {
        j.image[e] = eyes[e].waiting[best];
        j.info[e] = eyes[e].latest_info;
      }
      long unpaired = 0;
      for (auto& e : eyes) {
        for (auto it = e.waiting.begin(); it != e.waiting.end() && it->first < best;) {
          it = e.waiting.erase(it);
          ++unpaired;
        }
        e.waiting.erase(best);
      }
      {
        std::lock_guard<std::mutex> lock(stats_mu);
        st.unpaired += unpaired;
      }
      enqueue(std::move(j));
    }
    long evicted = 0;
    for (auto& e : eyes)
      while (e.waiting.size() > 8) {
        e.waiting.erase(e.waiting.begin());
        ++evicted;
      }
    if (evicted > 0) {
      {
        std::lock_guard<std::mutex> lock(stats_mu);
        st.unpaired += evicted;
      }
      log.warn("unpaired", "vision_component: warning: " + eyes[0].image_topic + " and " +
                               eyes[1].image_topic + " have no images with equal stamps");
    }
  }

  // ---- service --------------------------------------------------------------------------------

  struct Pending {
    Server::Incoming in;
    int object = -1;
    long after_seq = 0;  // answered by the result of a frame with a larger seq
    double deadline = 0;
  };

  int objectId(const std::string& name) const {
    for (size_t i = 0; i < names.size(); ++i)
      if (names[i] == name) return static_cast<int>(i);
    return -1;
  }

  void reply(const Server::Incoming& in, bool found, const Pose& cMo, const std::string& error) {
    msg::DetectResponse rep{};
    rep.found = found;
    if (found) {
      for (int i = 0; i < 9; ++i) rep.rotation[i] = cMo.R(i / 3, i % 3);
      for (int i = 0; i < 3; ++i) rep.translation[i] = cMo.t[i];
    }
    rep.error = const_cast<char*>(error.c_str());
    std::lock_guard<std::mutex> lock(srv_mu);
    server->reply(in, rep);
  }

  void replyWith(const Server::Incoming& in, const Result& r) {
    if (!r.have) reply(in, false, Pose(), "no frame received yet");
    else reply(in, r.found, r.cMo, r.error);
  }

  void takeRequests() {
    std::vector<Server::Incoming> reqs;
    {
      std::lock_guard<std::mutex> lock(srv_mu);
      reqs = server->take();
    }
    for (auto& in : reqs) {
      {
        std::lock_guard<std::mutex> lock(stats_mu);
        ++st.requests;
      }
      const std::string name = in.request->object_name ? in.request->object_name : "";
      const double timeout = in.request->timeout_s;
      const int id = objectId(name);
      if (id < 0) {
        reply(in, false, Pose(), "unknown object '" + name + "'");
        continue;
      }
      if (!std::isfinite(timeout) || timeout < 0) {
        reply(in, false, Pose(), "timeout_s must be a finite number >= 0");
        continue;
      }
      std::unique_lock<std::mutex> lock(mu);
      if (timeout == 0) {
        const Result r = results[static_cast<size_t>(id)];
        lock.unlock();
        replyWith(in, r);
        continue;
      }
      Pending p{std::move(in), id, 0, steadyNow() + timeout};
      {
        std::lock_guard<std::mutex> s(stats_mu);
        p.after_seq = st.received;
      }
      pending.push_back(std::move(p));
    }
  }

  void expirePending() {
    std::vector<Pending> expired;
    {
      std::lock_guard<std::mutex> lock(mu);
      const double now = steadyNow();
      for (auto it = pending.begin(); it != pending.end();) {
        if (it->deadline <= now) {
          expired.push_back(std::move(*it));
          it = pending.erase(it);
        } else {
          ++it;
        }
      }
    }
    for (auto& p : expired) {
      char buf[96];
      std::snprintf(buf, sizeof buf, "timeout: no new frame's result within %.3g s",
                    p.in.request->timeout_s);
      reply(p.in, false, Pose(), buf);
    }
  }

  /// Stores the results of frame `seq` and answers the requests waiting for them.
  void record(long seq, const std::vector<Result>& r) {
    std::vector<Pending> ready;
    {
      std::lock_guard<std::mutex> lock(mu);
      results = r;
      for (auto it = pending.begin(); it != pending.end();) {
        if (seq > it->after_seq) {
          ready.push_back(std::move(*it));
          it = pending.erase(it);
        } else {
          ++it;
        }
      }
    }
    for (auto& p : ready) replyWith(p.in, r[static_cast<size_t>(p.object)]);
  }

  // ---- detector thread -------------------------------------------------------------------------

  void workLoop() {
    while (!stopping) {
      std::optional<Job> job = slot.take(0.2);
      if (job) process(*job, steadyNow());
    }
  }

  /// Checks a frame; empty when usable, else the one-line problem.
  std::string checkFrame(const Job& job, dds::GrayImage* gray,
                                                 Intrinsics* cam) const {
    for (size_t e = 0; e < eyes.size(); ++e) {
      const msg::Image& img = **job.image[e];
      gray[e] = dds::toGray(img);
      if (!gray[e].ok()) return eyes[e].image_topic + ": " + gray[e].error;
      if (!job.info[e]) return "no camera_info received on " + eyes[e].info_topic;
      const msg::CameraInfo& ci = **job.info[e];
      std::string err;
      const auto c = dds::toIntrinsics(ci, &err);
      if (!c) return eyes[e].info_topic + ": " + err;
      if (c->width != gray[e].gray.cols || c->height != gray[e].gray.rows)
        return eyes[e].info_topic + " is " + std::to_string(c->width) + "x" +
               std::to_string(c->height) + " but " + eyes[e].image_topic + " is " +
               std::to_string(gray[e].gray.cols) + "x" + std::to_string(gray[e].gray.rows);
      if (frameOf(img.header) != frameOf(ci.header))
        return eyes[e].image_topic + ": frame '" + frameOf(img.header) + "' has no camera_info (" +
               eyes[e].info_topic + " is for frame '" + frameOf(ci.header) + "')";
      cam[e] = *c;
    }
    return "";
  }

  /// The image's capture stamp (its header, the camera's clock) and the component's frame counter.
  static FrameStamp frameStamp(const Job& job) {
    return {dds::fromRosTime((**job.image[0]).header.stamp), job.seq};
  }

  /// \param taken_at when the detector thread took the job from the slot (steady clock).
  void process(const Job& job, double taken_at) {
    dds::GrayImage gray[2];
    Intrinsics cam[2];
    const msg::Header& header = (**job.image[0]).header;
    std::vector<Result> res(names.size());
    for (auto& r : res) r.have = true;
    std::vector<std::pair<int, Pose>> found;  // (object, cMo) of every instance found
    std::vector<int> inliers(names.size(), 0);

    std::string problem = checkFrame(job, gray, cam);
    const double t0 = steadyNow();
    bool tracked_only = false;
    if (problem.empty() && pipeline) {
      // --track: the robot's pipeline (detect, confirm, track, re-detect).
      const servo::TargetFrame tf = trackFrame(job, gray, cam);
      if (!tf.ok) problem = eyes[0].image_topic + ": " + tf.error;
      tracked_only = tf.ok && tf.detector_calls == 0;
      for (const servo::TargetState& s : tf.objects) {
        if (!s.cMo || !s.confirmed) continue;  // an unconfirmed pose is not published
        found.emplace_back(s.object, *s.cMo);
        Result& o = res[static_cast<size_t>(s.object)];
        o.found = true;
        o.cMo = *s.cMo;
        inliers[static_cast<size_t>(s.object)] =
            s.mode == servo::TrackMode::kDetect ? s.detection.inliers : s.quality.features + s.quality_right.features;
      }
    } else if (problem.empty()) {
      // The one place the detector runs.
      if (eyes.size() == 1) {
        const detector::DetectionResult r = det.detect(gray[0].gray, cam[0], frameStamp(job));
        if (!r.ok) problem = eyes[0].image_topic + ": " + r.error;
        for (const auto& d : r.detections) {
          if (!d.found || !d.cMo) continue;
          found.emplace_back(d.object, *d.cMo);
          Result& o = res[static_cast<size_t>(d.object)];
          if (d.instance == 0) {
            o.found = true;
            o.cMo = *d.cMo;
            inliers[static_cast<size_t>(d.object)] = d.inliers;
          }
        }
      } else {
        const StereoRig rig{cam[0], cam[1], opt.stereo->lMr};
        const detector::StereoDetectionResult r =
            det.detectStereo(gray[0].gray, gray[1].gray, rig, frameStamp(job));
        if (!r.ok) problem = eyes[0].image_topic + ": " + r.error;
        for (const auto& s : r.objects) {
          if (!s.fused.lMo) continue;
          found.emplace_back(s.object, *s.fused.lMo);
          Result& o = res[static_cast<size_t>(s.object)];
          o.found = true;
          o.cMo = *s.fused.lMo;
          inliers[static_cast<size_t>(s.object)] = s.left.inliers + s.right.inliers;
        }
      }
    }
    const double t1 = steadyNow();
    if (!problem.empty()) {
      // The trackers do not carry a pose across a frame they did not see.
      if (pipeline) pipeline->failed(frameStamp(job), problem);
      found.clear();
      for (auto& r : res) {
        r.found = false;
        r.error = problem;
      }
      // One warning per kind of problem: the same message up to its numbers.
      std::string key = problem;
      for (char& ch : key)
        if (ch >= '0' && ch <= '9') ch = '#';
      log.warn(key, "vision_component: warning: " + problem + " (found = false)");
    }
    publish(header, res, found, inliers);
    const double t2 = steadyNow();
    {
      std::lock_guard<std::mutex> lock(stats_mu);
      if (problem.empty()) {
        ++st.processed;
        st.tracked += tracked_only;
        const double queue = taken_at - job.queued_at;
        detect_ms.push_back((t1 - t0) * 1e3);
        queue_ms.push_back(queue * 1e3);
        overhead_ms.push_back(((t2 - job.received_at) - (t1 - t0) - queue) * 1e3);
        for (auto* v : {&detect_ms, &queue_ms, &overhead_ms})
          if (v->size() > 2000) v->pop_front();
        st.last_detect_ms = detect_ms.back();
        st.last_queue_ms = queue_ms.back();
        st.last_overhead_ms = overhead_ms.back();
      } else {
        ++st.rejected;
      }
    }
    record(job.seq, res);
  }

  /// The frame through the pipeline (--track); stamps and counter as the detector gets them.
  servo::TargetFrame trackFrame(const Job& job, const dds::GrayImage* gray, const Intrinsics* cam) {
    const FrameStamp fs = frameStamp(job);
    if (eyes.size() == 1) {
      robot::MonoFrame f;
      f.image = gray[0].gray;
      f.stamp = fs.stamp;
      f.index = fs.index;
      return pipeline->process(f, cam[0]);
    }
    robot::StereoFrame f;
    f.left = gray[0].gray;
    f.right = gray[1].gray;
    f.stamp = fs.stamp;
    f.index = fs.index;
    return pipeline->process(f, StereoRig{cam[0], cam[1], opt.stereo->lMr});
  }

  void publish(const msg::Header& image_header, const std::vector<Result>& res,
               const std::vector<std::pair<int, Pose>>& found, const std::vector<int>& inliers) {
    const msg::Header h = image_header;  // the image's stamp and optical frame (borrowed)
    if (res[0].found) {
      msg::PoseStamped ps{};
      ps.header = h;
      ps.pose = dds::toRosPose(res[0].cMo);
      pose_w->write(ps);
    }
    std::vector<msg::ObjectHypothesisWithPose> hyp(found.size());
    std::vector<msg::Detection3D> d3(found.size());
    std::vector<std::string> ids(found.size());
    std::vector<int> instance(names.size(), 0);
    for (size_t k = 0; k < found.size(); ++k) {
      const auto& [obj, cMo] = found[k];
      const detector::ObjectModel& m = det.object(obj);
      hyp[k].hypothesis.class_id = const_cast<char*>(names[static_cast<size_t>(obj)].c_str());
      hyp[k].hypothesis.score = 1.0;  // a sanity-checked detection; inliers are in object_info
      hyp[k].pose.pose = dds::toRosPose(cMo);
      d3[k].header = h;
      d3[k].results = {1, 1, &hyp[k], false};
      // The box around the pattern: its centre and extent on the object plane.
      const auto& c = m.target->corners_o;
      const Eigen::Vector3d centre = (c[0] + c[1] + c[2] + c[3]) / 4.0;
      d3[k].bbox.center = dds::toRosPose(cMo * Pose(Eigen::Matrix3d::Identity(), centre));
      d3[k].bbox.size = {(c[1] - c[0]).norm(), (c[3] - c[0]).norm(), 0.0};
      ids[k] = names[static_cast<size_t>(obj)] + "#" + std::to_string(instance[static_cast<size_t>(obj)]++);
      d3[k].id = const_cast<char*>(ids[k].c_str());
    }
    msg::Detection3DArray arr{};
    arr.header = h;
    arr.detections = {static_cast<uint32_t>(d3.size()), static_cast<uint32_t>(d3.size()), d3.data(), false};
    det_w->write(arr);
    for (size_t i = 0; i < names.size(); ++i) {
      msg::ObjectInfo oi{};
      oi.header = h;
      oi.object_name = const_cast<char*>(names[i].c_str());
      oi.found = res[i].found;
      const Pose& P = res[i].cMo;
      for (int k = 0; k < 9; ++k) oi.rotation[k] = res[i].found ? P.R(k / 3, k % 3) : 0.0;
      for (int k = 0; k < 3; ++k) oi.translation[k] = res[i].found ? P.t[k] : 0.0;
      oi.inliers = res[i].found ? inliers[i] : 0;
      info_w->write(oi);
    }
  }

  detector::Detector det;
  VisionComponentOptions opt;
  std::unique_ptr<servo::TargetTracker> pipeline;  ///< --track (uses det)
  RateLimitedLog log;
  std::vector<std::string> names;

  dds::Participant pp;
  dds::WaitSet ws;
  std::vector<Eye> eyes;
  std::unique_ptr<dds::Writer<msg::PoseStamped>> pose_w;
  std::unique_ptr<dds::Writer<msg::Detection3DArray>> det_w;
  std::unique_ptr<dds::Writer<msg::ObjectInfo>> info_w;
  std::unique_ptr<Server> server;
  std::mutex srv_mu;  ///< the server's replies come from both threads

  LatestSlot<Job> slot;
  std::mutex mu;  ///< results, pending
  std::vector<Result> results;
  std::vector<Pending> pending;

  mutable std::mutex stats_mu;
  ComponentStats st;
  std::deque<double> detect_ms, queue_ms, overhead_ms;

  std::atomic<bool> stopping{false};
  std::thread rx, worker;
};

VisionComponent::VisionComponent(detector::Detector detector, const VisionComponentOptions& options,
                                 WarningSink warn) {
  options.check();
  p_ = std::make_unique<Impl>(std::move(detector), options, std::move(warn));
}

VisionComponent::~VisionComponent() { stop(); }

void VisionComponent::stop() {
  if (p_) p_->stop();
}

ComponentStats VisionComponent::stats() const {
  std::lock_guard<std::mutex> lock(p_->stats_mu);
  ComponentStats s = p_->st;
  s.detect_ms_median = median(p_->detect_ms);
  s.queue_ms_median = median(p_->queue_ms);
  s.overhead_ms_median = median(p_->overhead_ms);
  return s;
}

}  // namespace refgrasp::component
