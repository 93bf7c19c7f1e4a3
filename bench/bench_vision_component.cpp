// Timer harness for the DDS vision component at 640x480 (loopback, one process: a camera
// publisher, the component, a listener on object_info):
//   - latency: one frame at a time (the next one only after the result came back), from the
//     camera's dds_write of the image to the listener's take of object_info, against the bare
//     detector (Detector::detect on the same frame in this process, interleaved): the component
//     adds transport of the image (one serialisation + one deserialisation copy), its checks and
//     the result messages; mono8 pixels are used in place (no copy), colour is converted once;
//   - throughput: frames published at --rate for --seconds; frames the component processes per
//     second, and how many it dropped (newest-frame policy).
// --track: the component runs the robot's pipeline (servo::TargetTracker) and the frames are a
// rendered orbit (robot/sim/synthetic_sequence.h) so that there is something to track; the
// throughput line adds the frames tracked without the detector and the poses published.
// Target: < 2 ms added over the bare detector. Wall-clock figures depend on the machine's load.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <opencv2/imgproc.hpp>
#include <random>
#include <string>
#include <thread>

#include "component/vision_component.h"
#include "robot/dds/convert.h"
#include "robot/dds/transport.h"
#include "bench_util.h"
#include "robot/sim/synthetic_scene.h"
#include "robot/sim/synthetic_sequence.h"

using namespace refgrasp;
using namespace refgrasp::testing;

namespace {

using bench::Clock;
using bench::median;
double now() { return std::chrono::duration<double>(Clock::now().time_since_epoch()).count(); }

struct Scene {
  cv::Mat gray, bgr;
};

void usage() {
  std::printf(
      "bench_vision_component: latency the DDS vision component adds over the bare detector, and\n"
      "the frame rate it sustains, on seeded 640x480 frames (20 cm target at 0.35-0.9 m).\n"
      "Usage: bench_vision_component [--frames N (default 30)] [--rate HZ (default 30)]\n"
      "                              [--seconds S (default 10)] [--domain D (default 231)] [--track]\n"
      "                              [--help]\n"
      "--track: the component tracks between detections (vision_component --track); the frames\n"
      "are then a rendered orbit around the target (0.4-1.8 m, tilts to 50 deg), played in a loop.\n"
      "Uses CYCLONEDDS_URI, or config/dds/cyclonedds_loopback.xml when it is not set.\n");
}

}  // namespace

int main(int argc, char** argv) try {
  int frames = 30, domain = 231;
  double rate = 30, seconds = 10;
  bool track = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      usage();
      return 0;
    } else if (a == "--frames" && i + 1 < argc) {
      frames = static_cast<int>(bench::intArg("bench_vision_component", "--frames", argv[++i], 1));
    } else if (a == "--rate" && i + 1 < argc) {
      rate = bench::numberArg("bench_vision_component", "--rate", argv[++i], 0.1);
    } else if (a == "--seconds" && i + 1 < argc) {
      seconds = bench::numberArg("bench_vision_component", "--seconds", argv[++i], 1.0);
    } else if (a == "--track") {
      track = true;
    } else if (a == "--domain" && i + 1 < argc) {
      domain = static_cast<int>(bench::intArg("bench_vision_component", "--domain", argv[++i], 0));
    } else {
      usage();
      return 2;
    }
  }
  if (!std::getenv("CYCLONEDDS_URI")) {
    const std::string uri = "file://" + std::string(REFGRASP_SOURCE_DIR) + "/config/dds/cyclonedds_loopback.xml";
    setenv("CYCLONEDDS_URI", uri.c_str(), 1);
  }
  std::printf("CYCLONEDDS_URI=%s\n", std::getenv("CYCLONEDDS_URI"));

  const char* kTexture = "targets/cereal_box.png";
  const cv::Mat tex = loadMedia(kTexture);
  const double w = 0.2, h = w * tex.rows / tex.cols;
  const detector::ObjectModel object = detector::textureObject("cereal_box", tex, w);
  std::vector<Scene> scenes;
  std::mt19937_64 rng(7);
  if (track) {
    TrackingSequenceSpec seq_spec;
    seq_spec.frames = std::max(frames, 2);
    seq_spec.texture = kTexture;
    seq_spec.width_m = w;
    for (const robot::MonoFrame& f : renderTrackingSequence(seq_spec).mono) {
      Scene s;
      s.gray = f.image;
      cv::cvtColor(s.gray, s.bgr, cv::COLOR_GRAY2BGR);
      scenes.push_back(s);
    }
  }
  for (int i = 0; i < frames && !track; ++i) {
    SceneSpec spec;
    spec.cMo = randomVisiblePose(rng, sceneCamera(), w, h, 0.35, 0.9, 35 * M_PI / 180);
    spec.seed = 100 + static_cast<uint64_t>(i);
    Scene s;
    s.gray = renderTarget(sceneCamera(), tex, w, h, spec).image;
    cv::cvtColor(s.gray, s.bgr, cv::COLOR_GRAY2BGR);
    scenes.push_back(s);
  }

  detector::Detector bare, inside;
  bare.addObject(object);
  inside.addObject(object);
  const std::string ns = "/bench_" + std::to_string(::getpid());
  component::VisionComponentOptions opt;
  opt.domain = domain;
  opt.ns = ns;
  opt.track = track;
  component::VisionComponent vc(std::move(inside), opt);

  dds::Participant pp(domain);
  dds::Writer<dds::msg::Image> img_w(pp, dds::ddsTopicName(ns + "/image_raw"), dds::QosProfile::sensorData());
  dds::Writer<dds::msg::CameraInfo> info_w(pp, dds::ddsTopicName(ns + "/camera_info"), dds::QosProfile::reliable(1));
  dds::Reader<dds::msg::ObjectInfo> info_r(pp, dds::ddsTopicName(ns + "/object_info"), dds::QosProfile::reliable(100));
  dds::WaitSet ws(pp);
  ws.attach(info_r.condition(), 1);
  if (!img_w.waitForMatch(1, 10) || !info_r.waitForMatch(1, 10)) {
    std::fprintf(stderr, "bench_vision_component: the component did not match\n");
    return 1;
  }
  const std::string frame = "camera";
  auto publish = [&](const cv::Mat& image, Seconds stamp) {
    dds::CameraInfoOut ci(sceneCamera(), stamp, frame);
    info_w.write(ci.msg());
    dds::ImageOut im(image, stamp, frame);
    img_w.write(im.msg());
  };
  // Waits for the object_info of the frame stamped `stamp`; the time it was taken, or NaN.
  auto waitResult = [&](Seconds stamp, double timeout_s) {
    const dds::msg::Time want = dds::toRosTime(stamp);
    const double end = now() + timeout_s;
    while (now() < end) {
      for (auto& s : info_r.takeAll())
        if (s->header.stamp.sec == want.sec && s->header.stamp.nanosec == want.nanosec) return now();
      ws.wait(std::max(0.0, end - now()));
    }
    return double(NAN);
  };
  // Warm-up: discovery on both sides (best-effort images may be lost until then).
  for (int k = 0; k < 50; ++k) {
    publish(scenes[0].gray, 0.5 + k);
    if (!std::isnan(waitResult(0.5 + k, 2))) break;
  }

  // ---- latency, one frame at a time ------------------------------------------------------------
  struct Row {
    const char* name;
    std::vector<double> bare_ms, e2e_ms, added_ms, own_ms;
  } rows[2] = {{"mono8 (used in place)", {}, {}, {}, {}}, {"bgr8 (converted once)", {}, {}, {}, {}}};
  Seconds stamp = 100;
  long processed_before = vc.stats().processed;
  for (int enc = 0; enc < 2; ++enc) {
    for (const Scene& s : scenes) {
      const cv::Mat& image = enc == 0 ? s.gray : s.bgr;
      double t0 = now();
      cv::Mat gray;
      if (enc == 1) cv::cvtColor(image, gray, cv::COLOR_BGR2GRAY);
      const detector::DetectionResult r = bare.detect(enc == 0 ? image : gray, sceneCamera());
      rows[enc].bare_ms.push_back((now() - t0) * 1e3);
      (void)r;
      stamp += 1;
      // The camera info goes first (as a driver publishes them), outside the timed span.
      dds::CameraInfoOut ci(sceneCamera(), stamp, frame);
      info_w.write(ci.msg());
      dds::ImageOut im(image, stamp, frame);
      t0 = now();
      img_w.write(im.msg());
      const double t1 = waitResult(stamp, 10);
      if (std::isnan(t1)) {
        std::fprintf(stderr, "bench_vision_component: no result for a frame (lost?)\n");
        continue;
      }
      // The component updates its statistics just after writing the results: wait for them.
      component::ComponentStats st = vc.stats();
      while (st.processed < processed_before + 1) {
        std::this_thread::sleep_for(std::chrono::microseconds(200));
        st = vc.stats();
      }
      processed_before = st.processed;
      rows[enc].e2e_ms.push_back((t1 - t0) * 1e3);
      // What this frame cost beyond the detector's own time on it (same frame, same thread).
      rows[enc].added_ms.push_back((t1 - t0) * 1e3 - st.last_detect_ms);
      rows[enc].own_ms.push_back(st.last_overhead_ms);
    }
  }
  const component::ComponentStats paced = vc.stats();

  // ---- throughput --------------------------------------------------------------------------------
  const component::ComponentStats before = vc.stats();
  const double t_start = now();
  long published = 0, poses = 0;
  for (auto& s : info_r.takeAll()) (void)s;
  for (double t = t_start; now() - t_start < seconds; t += 1.0 / rate) {
    stamp += 1;
    publish(scenes[static_cast<size_t>(published) % scenes.size()].gray, stamp);
    ++published;
    for (auto& s : info_r.takeAll()) poses += s->found;
    const double wait = t + 1.0 / rate - now();
    if (wait > 0) std::this_thread::sleep_for(std::chrono::duration<double>(wait));
  }
  waitResult(stamp, 10);  // the newest one is always processed
  const double elapsed = now() - t_start;
  const component::ComponentStats after = vc.stats();
  vc.stop();

  std::printf("\nLatency, one 640x480 frame at a time (%d frames each; medians, ms):\n", frames);
  std::printf("| image | bare detector (separate run) | component end to end | added: end to end - detector on that frame | of which the component's own work |\n|---|---|---|---|---|\n");
  for (const Row& row : rows)
    std::printf("| %s | %.1f | %.1f | %.2f | %.3f |\n", row.name, median(row.bare_ms), median(row.e2e_ms),
                median(row.added_ms), median(row.own_ms));
  std::printf("(added = image transport camera -> component, its checks/conversion, the result "
              "messages and their transport to the listener; waiting for the detector: %.2f ms median)\n",
              paced.queue_ms_median);
  const long received = after.received - before.received, processed = after.processed - before.processed,
             dropped = after.dropped - before.dropped;
  std::printf("\nThroughput: %ld mono8 frames published at %.0f Hz for %.1f s: %ld taken by the "
              "component, %ld processed (%.1f frames/s), %ld dropped (newest-frame policy), %ld lost "
              "in transport (best effort, keep last 1)\n",
              published, rate, elapsed, received, processed, processed / elapsed, dropped,
              published - received);
  if (track)
    std::printf("--track: %ld of the processed frames tracked without the detector, %ld poses "
                "published during the run (%.1f per second); pipeline median %.2f ms a frame\n",
                after.tracked - before.tracked, poses, poses / elapsed, after.detect_ms_median);
  std::printf("Bare detector rate on this machine: %.1f frames/s (1 / median)\n", 1e3 / median(rows[0].bare_ms));
  return 0;
}
catch (const std::exception& e) {  // a missing or unreadable input: one line, not an abort
  std::fprintf(stderr, "bench_vision_component: %s\n", e.what());
  return 1;
}
