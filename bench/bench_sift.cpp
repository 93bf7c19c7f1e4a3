// Timer harness for SIFT extraction and whole detection with both extractors (cv::SIFT of OpenCV
// 4.6 and the project's fast SIFT), on seeded 640x480 cluttered frames with a target: extraction
// alone (1 and N threads), the fast extractor's stages, whole detection, a pipelined stream (one
// frame per thread), stereo pairs and ROI re-detection. Prints medians next to the paper's figures
// and the camera's 48 fps. Wall-clock: run it on a quiet machine.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <sys/resource.h>
#include <string>
#include <thread>
#include <vector>

#include "bench_util.h"
#include "robot/sim/synthetic_scene.h"
#include "detector/detector.h"
#include "detector/sift_fast.h"
#include "eval/sift_equivalence.h"

using namespace refgrasp;
using namespace refgrasp::detector;
using namespace refgrasp::testing;

namespace {

using bench::Clock;
using bench::median;
using bench::threadCpuMs;
using bench::timeMs;

void usage() {
  std::printf(
      "bench_sift: SIFT extraction and detection timings, cv::SIFT (OpenCV 4.6) vs the project's\n"
      "fast SIFT, on seeded 640x480 cluttered frames with a 20 cm target at 0.3-1.2 m (tilt 0-50\n"
      "deg, noise 2, blur <= 1.5 px), full frame, the paper's 2x up-sampling. Rows (medians):\n"
      "  extraction alone, 1 thread (wall and thread CPU time) and --threads threads inside the\n"
      "    frame (latency); the fast extractor's stages (1 thread, CPU time);\n"
      "  whole detection (Detector::detect: paper matcher + refined pose), 1 thread (CPU time) and\n"
      "    --threads inside;\n"
      "  stream: all frames pipelined, one frame per worker thread (--threads workers, 1 thread\n"
      "    inside each), frames per second (the Bumblebee2 delivers 48) and per-frame latency;\n"
      "  stereo pairs: Detector::detectStereo, pairs pipelined one per worker, pairs per second, and\n"
      "    the CPU time of a pair on 1 thread;\n"
      "  ROI extraction: extractSift on the target's bounding box + 16 px, keypoint sizes 2-40 px;\n"
      "  ROI re-detection: Detector::detect with the target's pose as the prior (the tracker's\n"
      "    prediction: its region and keypoint size range), wall and CPU time.\n"
      "  Then the CPU-time bounds on --threads cores and the issue's targets (>= 48 fps, latency\n"
      "  < 40 ms, >= 24 stereo pairs/s, re-detection < 10 ms), wall clock and CPU-time bound.\n"
      "  Per-frame rows: medians over the first min(N, 48) frames; the stream and stereo rows: all N.\n"
      "  Machine probe: a fixed register-only multiply-add loop (no memory traffic) timed alone and\n"
      "    on --threads threads at once, before and after each extractor's stream rows, relative to\n"
      "    its fastest time in the run: > 1 means the host gave this VM less compute then.\n"
      "The issue's final table (wall clock, both extractors): on an otherwise idle machine run\n"
      "    build/bench/bench_sift\n"
      "  with no arguments (= --frames 200 --threads 2 --seed 1); it prints the load average before and\n"
      "  after, and its own run time (2-3 minutes idle; 206 s of CPU time on a loaded 2-core VM).\n"
      "Usage: bench_sift [--frames N (default 200)] [--threads T (default 2)] [--seed S (default 1)]\n"
      "                  [--texture media/relative.png] [--only fast|opencv] [--help]\n"
      "       bench_sift --stages [--frames N]: the fast extractor only, 1 thread: stage CPU medians,\n"
      "         candidate/extremum/keypoint counts, a fingerprint of the output (bit-for-bit checks)\n"
      "         and page faults per frame.\n"
      "       bench_sift --profile extract|detect|roi|redetect [--frames N] [--only fast|opencv]: no\n"
      "         timings (redetect: Detector::detect with the target's pose as the prior);\n"
      "         one warm-up, then that operation on each frame, 1 thread, inside profiledRegion()\n"
      "         for valgrind --tool=callgrind --toggle-collect=profiledRegion (instruction counts).\n"
      "       bench_sift --equivalence: no timings; the fast SIFT against cv::SIFT on the same images\n"
      "         (the sets of ctest -R SiftFast.Equivalent, eval/sift_equivalence.h): per set the\n"
      "         keypoints of each (cv, fast), recall and precision (a counterpart within 0.5 px, 5 %%\n"
      "         in size, 5 deg), counterparts equal to the bit (same), the largest position\n"
      "         difference (dpos, px), descriptor L2 distances median / 99 %% / max (of ~512).\n"
      "Wall-clock figures: run on an otherwise idle machine. REFGRASP_SIFT_ISA=avx2|scalar lowers\n"
      "the fast extractor's kernels.\n");
}

struct Frame {
  cv::Mat left, right;
  cv::Rect roi;  ///< target bounding box (left eye) + 16 px
  Pose cMo;      ///< the target in the left camera frame (the re-detection's prior)
};

/// The 1, 5 and 15 minute load averages (/proc/loadavg), for the header of the report.
std::string loadAverage() {
  char buf[64] = "?";
  if (FILE* f = std::fopen("/proc/loadavg", "r")) {
    double a = 0, b = 0, c = 0;
    if (std::fscanf(f, "%lf %lf %lf", &a, &b, &c) == 3) std::snprintf(buf, sizeof buf, "%.1f %.1f %.1f", a, b, c);
    std::fclose(f);
  }
  return buf;
}

struct Row {
  const char* name;
  double opencv = NAN, fast = NAN;
  const char* unit;
  const char* paper;
};

SiftOptions siftFor(SiftImplementation impl, int threads) {
  SiftOptions o;
  o.implementation = impl;
  o.threads = threads;
  return o;
}

void printEquivalenceHeader() {
  std::printf("| %-32s | %6s | %6s | %7s | %7s | %7s | %5s | %4s | %4s | %5s |\n", "set", "cv", "fast", "recall",
              "precis.", "same", "dpos", "dmed", "d99", "dmax");
}

void printEquivalenceRow(const std::string& set, const eval::SiftAgreement& g) {
  std::printf("| %-32s | %6d | %6d | %6.2f%% | %6.2f%% | %6.2f%% | %5.2g | %4.1f | %4.1f | %5.1f |\n", set.c_str(),
              g.reference, g.fast, 100 * g.recall(), 100 * g.precision(), 100 * g.identicalFraction(), g.max_pos,
              g.descQuantile(0.5), g.descQuantile(0.99), g.descQuantile(1.0));
  for (const std::string& p : g.problems) std::printf("  %s: %s\n", set.c_str(), p.c_str());
}

/// The equivalence tables: the default options' sets, then the other options (and their total).
void equivalence() {
  printEquivalenceHeader();
  for (const eval::SiftEquivalenceRow& r : eval::siftEquivalenceDefaultOptions()) printEquivalenceRow(r.set, r.agreement);
  printEquivalenceHeader();
  eval::SiftAgreement all;
  for (const eval::SiftEquivalenceRow& r : eval::siftEquivalenceOtherOptions()) {
    printEquivalenceRow(r.set, r.agreement);
    all.add(r.agreement);
  }
  printEquivalenceRow("other options and sizes (all)", all);
}

/// Runs fn(frame index) over all frames on `workers` threads, each taking the next frame; returns
/// the wall time (ms) and fills per-frame latencies.
template <class F>
double stream(int n, int workers, std::vector<double>* latency, F fn) {
  std::atomic<int> next{0};
  latency->assign(n, 0);
  const auto t0 = Clock::now();
  std::vector<std::thread> pool;
  for (int w = 0; w < workers; ++w)
    pool.emplace_back([&, w] {
      for (int i; (i = next.fetch_add(1)) < n;) (*latency)[i] = timeMs([&] { fn(w, i); });
    });
  for (auto& t : pool) t.join();
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

/// The machine's compute speed at this moment: a fixed loop of multiply-adds on registers only
/// (eight independent chains, no memory traffic), run on `threads` threads at once; returns the
/// slowest thread's wall time (ms). On this project's VMs the same loop takes from 1.0x to 1.5x its
/// fastest time, alone or with both vCPUs busy: the host shares the cores. Printed beside the
/// stream rows so that a wall-clock figure can be read against the speed it ran at.
volatile float probe_sink;  // keeps each probe loop's result alive

double probeMs(int threads) {
  std::vector<double> ms(threads, 0);
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t)
    pool.emplace_back([&, t] {
      ms[t] = timeMs([&] {
        volatile float seed = 1e-3f * static_cast<float>(t + 1);
        const float k = 0.99999f, b = 1e-6f;
        float a[8];
        for (int c = 0; c < 8; ++c) a[c] = seed + static_cast<float>(c);
        for (int n = 0; n < 40000000; ++n)
          for (int c = 0; c < 8; ++c) a[c] = a[c] * k + b;
        float s = 0;
        for (float v : a) s += v;
        probe_sink = s;
      });
    });
  for (auto& th : pool) th.join();
  return *std::max_element(ms.begin(), ms.end());
}

/// "alone X ms, N at once Y ms": the probe on 1 thread, then on `threads` threads.
struct Probe {
  double alone = NAN, together = NAN;
};
Probe probe(int threads) { return {probeMs(1), probeMs(threads)}; }

/// The operation --profile measures, not inlined so that callgrind can collect only it.
template <class F>
__attribute__((noinline)) void profiledRegion(F&& f) {
  f();
}

}  // namespace

int main(int argc, char** argv) try {
  int frames = 200, threads = 2;
  uint64_t seed = 1;
  std::string texture = "targets/poster_concert.png", only, profile;
  bool stages_only = false, equivalence_only = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      usage();
      return 0;
    } else if (a == "--frames" && i + 1 < argc) {
      frames = static_cast<int>(bench::intArg("bench_sift", "--frames", argv[++i], 1));
    } else if (a == "--threads" && i + 1 < argc) {
      threads = static_cast<int>(bench::intArg("bench_sift", "--threads", argv[++i], 1));
    } else if (a == "--seed" && i + 1 < argc) {
      seed = static_cast<uint64_t>(bench::intArg("bench_sift", "--seed", argv[++i], 0));
    } else if (a == "--texture" && i + 1 < argc) {
      texture = argv[++i];
    } else if (a == "--profile" && i + 1 < argc) {
      profile = argv[++i];
      if (profile != "extract" && profile != "detect" && profile != "roi" && profile != "redetect") {
        std::fprintf(stderr, "bench_sift: --profile takes extract, detect, roi or redetect\n");
        return 2;
      }
    } else if (a == "--stages") {
      stages_only = true;
    } else if (a == "--equivalence") {
      equivalence_only = true;
    } else if (a == "--only" && i + 1 < argc) {
      only = argv[++i];
      if (only != "fast" && only != "opencv") {
        std::fprintf(stderr, "bench_sift: --only takes fast or opencv\n");
        return 2;
      }
    } else {
      bench::rejectArgument("bench_sift", a, {"--frames", "--threads", "--seed", "--texture", "--profile", "--only"});
    }
  }
  if (equivalence_only) {
    equivalence();
    return 0;
  }
  const auto run_start = Clock::now();
  const cv::Mat tex = loadMedia(texture);
  const double w = 0.2, h = w * tex.rows / tex.cols;
  const Intrinsics cam = sceneCamera();
  StereoRig rig;
  rig.left = rig.right = cam;
  rig.lMr = Pose(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.12, 0, 0));

  // Frames, rendered up front (not timed).
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> blur(0.0, 1.5), angle(0, M_PI);
  std::vector<Frame> data(frames);
  for (int i = 0; i < frames; ++i) {
    SceneSpec spec;
    spec.cMo = randomVisiblePose(rng, cam, w, h, 0.3, 1.2, 50 * M_PI / 180);
    spec.motion_blur_px = blur(rng);
    spec.motion_blur_angle_rad = angle(rng);
    spec.seed = seed * 1000 + i;
    const RenderedScene l = renderTarget(cam, tex, w, h, spec);
    data[i].cMo = spec.cMo;
    spec.cMo = rig.lMr.inverse() * spec.cMo;  // rMo
    spec.seed += 500000;
    data[i].left = l.image;
    data[i].right = renderTarget(cam, tex, w, h, spec).image;
    cv::Rect box = cv::boundingRect(std::vector<cv::Point2f>{
        cv::Point2f(l.corners[0].x(), l.corners[0].y()), cv::Point2f(l.corners[1].x(), l.corners[1].y()),
        cv::Point2f(l.corners[2].x(), l.corners[2].y()), cv::Point2f(l.corners[3].x(), l.corners[3].y())});
    box.x -= 16, box.y -= 16, box.width += 32, box.height += 32;
    data[i].roi = box & cv::Rect(0, 0, cam.width, cam.height);
  }
  if (!profile.empty()) {
    cv::setNumThreads(1);
    const SiftImplementation impl = only == "opencv" ? SiftImplementation::kOpenCV : SiftImplementation::kFast;
    DetectorOptions dopt;
    dopt.sift = siftFor(impl, 1);
    Detector det(dopt);
    det.addObject(textureObject("target", tex, w));
    ExtractRegion region;
    region.min_size_px = 2;
    region.max_size_px = 40;
    long total = 0;
    auto run = [&](int i) {
      if (profile == "extract") {
        total += extractSift(data[i].left, siftFor(impl, 1)).size();
      } else if (profile == "detect") {
        total += det.detect(data[i].left, cam).find(0).has_value();
      } else if (profile == "roi") {
        region.roi = data[i].roi;
        total += extractSift(data[i].left, siftFor(impl, 1), region).size();
      } else {  // redetect: Detector::detect with the target's pose as the prior
        DetectionQuery q;
        ObjectPrior prior;
        prior.object = 0;
        prior.cMo = data[i].cMo;
        q.priors.push_back(prior);
        total += det.detect(data[i].left, cam, {}, q).find(0).has_value();
      }
    };
    run(0);  // warm-up: buffers, lazy initialisation
    total = 0;
    for (int i = 0; i < frames; ++i) profiledRegion([&] { run(i); });
    std::printf("bench_sift --profile %s (%s): %d frames, %ld %s\n", profile.c_str(),
                impl == SiftImplementation::kFast ? "fast" : "cv::SIFT", frames, total,
                profile == "detect" || profile == "redetect" ? "detections" : "features");
    return 0;
  }
  if (stages_only) {  // the fast extractor's stages, thread CPU time, 1 thread
    std::vector<double> st[5];
    uint64_t fingerprint = 1469598103934665603ull;
    long keypoints = 0, candidates = 0, extrema = 0, faults = 0, far_steps = 0;
    FastSiftCall call;
    call.isa = bestSiftIsa();
    call.threads = 1;
    for (int rep = 0; rep < 2; ++rep)
      for (int i = 0; i < frames; ++i) {
        FastSiftStats s;
        call.stats = &s;
        std::vector<cv::KeyPoint> k;
        cv::Mat d;
        rusage r0{}, r1{};
        getrusage(RUSAGE_THREAD, &r0);
        const double total = threadCpuMs([&] {
          fastSiftDetectAndCompute(data[i].left, siftFor(SiftImplementation::kFast, 1), call, &k, &d);
        });
        getrusage(RUSAGE_THREAD, &r1);
        if (rep == 1) faults += r1.ru_minflt - r0.ru_minflt;
        if (rep == 0) {  // warm-up pass; the fingerprint of the output (FNV-1a of every field)
          auto mix = [&](const void* p, size_t n) {
            for (size_t b = 0; b < n; ++b) fingerprint = (fingerprint ^ static_cast<const uint8_t*>(p)[b]) * 1099511628211ull;
          };
          for (const cv::KeyPoint& kp : k) {
            mix(&kp.pt, sizeof kp.pt);
            mix(&kp.size, sizeof kp.size);
            mix(&kp.angle, sizeof kp.angle);
            mix(&kp.response, sizeof kp.response);
            mix(&kp.octave, sizeof kp.octave);
          }
          for (int r = 0; r < d.rows; ++r) mix(d.ptr<float>(r), 128 * sizeof(float));
          keypoints += k.size();
          candidates += s.candidates;
          extrema += s.extrema;
          far_steps += s.far_steps;
          continue;
        }
        st[0].push_back(s.scale_space_cpu_ms);
        st[1].push_back(s.localise_cpu_ms);
        st[2].push_back(s.describe_cpu_ms);
        st[3].push_back(s.output_cpu_ms);
        st[4].push_back(total);
      }
    std::printf("fast extractor (%s), %d frames, thread CPU medians (ms): scale space %.2f | localisation %.2f | "
                "orientation + descriptors %.2f | output %.2f | total %.2f | %ld candidates (%ld far interpolation steps), %ld "
                "extrema, %ld keypoints, fingerprint %016llx | %.0f page faults per frame\n",
                siftIsaName(call.isa), frames, median(st[0]), median(st[1]), median(st[2]), median(st[3]),
                median(st[4]), candidates, far_steps, extrema, keypoints, static_cast<unsigned long long>(fingerprint),
                static_cast<double>(faults) / frames);
    return 0;
  }
  const int sample = std::min(frames, 48);  // frames for the per-frame medians
  std::vector<double> roi_area;
  Probe probe_before[2], probe_after[2];  // around each extractor's stream and stereo rows
  for (int i = 0; i < sample; ++i) roi_area.push_back(100.0 * data[i].roi.area() / (cam.width * cam.height));

  enum RowId {
    kExtract1, kExtract1Cpu, kDetect1Cpu, kExtractN, kDetectN, kStream, kStreamLatency, kStereo, kStereoCpu,
    kRoiExtract, kRoiExtractCpu, kRoiDetect, kRoiDetectCpu, kRowCount
  };
  std::vector<Row> rows(kRowCount);
  rows[kExtract1] = {"extraction, 1 thread", NAN, NAN, "ms", "SIFT++ ~3000 ms; its CUDA SIFT ~250 ms"};
  rows[kExtract1Cpu] = {"extraction, 1 thread, CPU time", NAN, NAN, "ms", "-"};
  rows[kDetect1Cpu] = {"whole detection, 1 thread, CPU time", NAN, NAN, "ms", "-"};
  rows[kExtractN] = {"extraction, N threads (latency)", NAN, NAN, "ms", "CUDA SIFT ~250 ms"};
  rows[kDetectN] = {"whole detection, N threads", NAN, NAN, "ms", "> 250 ms (SIFT alone)"};
  rows[kStream] = {"stream of frames, N workers", NAN, NAN, "fps", "< 4 fps; the camera: 48 fps"};
  rows[kStreamLatency] = {"stream latency per frame", NAN, NAN, "ms", "> 250 ms"};
  rows[kStereo] = {"stereo pairs, N workers", NAN, NAN, "pairs/s", "< 2 pairs/s (2 x 250 ms)"};
  rows[kStereoCpu] = {"stereo pair, 1 thread, CPU time", NAN, NAN, "ms", "-"};
  rows[kRoiExtract] = {"ROI extraction", NAN, NAN, "ms", "-"};
  rows[kRoiExtractCpu] = {"ROI extraction, CPU time", NAN, NAN, "ms", "-"};
  rows[kRoiDetect] = {"ROI re-detection (pose prior)", NAN, NAN, "ms", "-"};
  rows[kRoiDetectCpu] = {"ROI re-detection, CPU time", NAN, NAN, "ms", "-"};
  std::vector<double> stage[5], part[4], roi_part[4], redetect_area, redetect_min, redetect_max;
  // A detection's own stage times: extraction, matching, pose + checks, the rest.
  auto addStages = [](const DetectionResult& r, std::vector<double>* p) {
    const DetectionTimings& t = r.time_ms;
    p[0].push_back(t.extract);
    p[1].push_back(t.match);
    p[2].push_back(t.pose);
    p[3].push_back(t.total - t.extract - t.match - t.pose);
  };
  int features[2] = {0, 0}, found[2] = {0, 0}, stereo_found[2] = {0, 0}, roi_found[2] = {0, 0};
  const int saved_threads = cv::getNumThreads();
  const std::string load_before = loadAverage();

  for (int which = 0; which < 2; ++which) {
    const SiftImplementation impl = which == 0 ? SiftImplementation::kOpenCV : SiftImplementation::kFast;
    if ((only == "fast" && which == 0) || (only == "opencv" && which == 1)) continue;
    auto set = [&](RowId r, double v) { (which == 0 ? rows[r].opencv : rows[r].fast) = v; };
    // cv::SIFT's threads come from OpenCV's pool; the fast extractor's from SiftOptions.threads.
    auto limitOpenCv = [&](int n) { cv::setNumThreads(which == 0 ? n : saved_threads); };

    // Warm-up (page faults, lazy initialisation) outside the timings.
    extractSift(data[0].left, siftFor(impl, 1));

    std::vector<double> t1, c1, tn, troi, croi;
    limitOpenCv(1);
    for (int i = 0; i < sample; ++i) {
      Features f;
      t1.push_back(timeMs([&] { f = extractSift(data[i].left, siftFor(impl, 1)); }));
      c1.push_back(threadCpuMs([&] { extractSift(data[i].left, siftFor(impl, 1)); }));
      features[which] += f.size();
      if (which == 1) {  // the fast extractor's stages, from its own statistics (thread CPU time)
        FastSiftStats st;
        FastSiftCall call;
        call.isa = bestSiftIsa();
        call.threads = 1;
        call.stats = &st;
        std::vector<cv::KeyPoint> k;
        cv::Mat d;
        fastSiftDetectAndCompute(data[i].left, siftFor(impl, 1), call, &k, &d);
        stage[0].push_back(st.scale_space_cpu_ms);
        stage[1].push_back(st.localise_cpu_ms);
        stage[2].push_back(st.describe_cpu_ms);
        stage[3].push_back(st.output_cpu_ms);
        stage[4].push_back(st.candidates);
      }
    }
    limitOpenCv(threads);
    for (int i = 0; i < sample; ++i) tn.push_back(timeMs([&] { extractSift(data[i].left, siftFor(impl, threads)); }));
    ExtractRegion region;
    region.min_size_px = 2;
    region.max_size_px = 40;
    limitOpenCv(1);
    for (int i = 0; i < sample; ++i) {
      region.roi = data[i].roi;
      troi.push_back(timeMs([&] { extractSift(data[i].left, siftFor(impl, 1), region); }));
      croi.push_back(threadCpuMs([&] { extractSift(data[i].left, siftFor(impl, 1), region); }));
    }
    set(kExtract1, median(t1));
    set(kExtract1Cpu, median(c1));
    set(kExtractN, median(tn));
    set(kRoiExtract, median(troi));
    set(kRoiExtractCpu, median(croi));

    // Whole detection, threads inside the frame.
    limitOpenCv(threads);
    DetectorOptions dopt;
    dopt.sift = siftFor(impl, threads);
    Detector det(dopt);
    const int id = det.addObject(textureObject("target", tex, w));
    std::vector<double> tw;
    for (int i = 0; i < sample; ++i) {
      DetectionResult r;
      tw.push_back(timeMs([&] { r = det.detect(data[i].left, cam); }));
      found[which] += r.find(id).has_value();
    }
    set(kDetectN, median(tw));
    {  // one thread: what a frame costs a core (the stream's bound is --threads x 1000 / this);
       // OpenCV's own parallel loops (warps, ECC) kept on this thread so the clock sees them
      cv::setNumThreads(1);
      DetectorOptions one = dopt;
      one.sift = siftFor(impl, 1);
      Detector det1(one);
      const int id1 = det1.addObject(textureObject("target", tex, w));
      std::vector<double> cw, cs, rw, rc;
      for (int i = 0; i < sample; ++i) {
        DetectionResult r;
        cw.push_back(threadCpuMs([&] { r = det1.detect(data[i].left, cam); }));
        if (which == 1) addStages(r, part);
      }
      for (int i = 0; i < sample; ++i)
        cs.push_back(threadCpuMs([&] { det1.detectStereo(data[i].left, data[i].right, rig); }));
      // Re-detection with the tracker's prior: the predicted pose (here the true one) gives the
      // region and the keypoint size range (ObjectPrior's default margins).
      for (int i = 0; i < sample; ++i) {
        DetectionQuery q;
        ObjectPrior prior;
        prior.object = id1;
        prior.cMo = data[i].cMo;
        q.priors.push_back(prior);
        DetectionResult r;
        rw.push_back(timeMs([&] { r = det1.detect(data[i].left, cam, {}, q); }));
        rc.push_back(threadCpuMs([&] { det1.detect(data[i].left, cam, {}, q); }));
        if (which == 1) addStages(r, roi_part);
        roi_found[which] += r.find(id1).has_value();
        if (which == 1 && !r.stats.empty()) {
          redetect_area.push_back(100.0 * r.stats[0].roi.area() / (cam.width * cam.height));
          redetect_min.push_back(r.stats[0].min_keypoint_px);
          redetect_max.push_back(r.stats[0].max_keypoint_px);
        }
      }
      set(kDetect1Cpu, median(cw));
      set(kStereoCpu, median(cs));
      set(kRoiDetect, median(rw));
      set(kRoiDetectCpu, median(rc));
      cv::setNumThreads(saved_threads);
    }

    // Pipelined streams: one frame (or pair) per worker, one thread inside each.
    limitOpenCv(1);
    dopt.sift = siftFor(impl, 1);
    std::vector<Detector> dets;
    for (int k = 0; k < threads; ++k) {
      dets.emplace_back(dopt);
      dets.back().addObject(textureObject("target", tex, w));
    }
    std::vector<double> lat;
    probe_before[which] = probe(threads);
    const double wall = stream(frames, threads, &lat, [&](int wkr, int i) { dets[wkr].detect(data[i].left, cam); });
    set(kStream, 1000.0 * frames / wall);
    set(kStreamLatency, median(lat));
    std::vector<int> sfound(frames, 0);
    const double swall = stream(frames, threads, &lat, [&](int wkr, int i) {
      const StereoDetectionResult r = dets[wkr].detectStereo(data[i].left, data[i].right, rig);
      sfound[i] = !r.objects.empty() && r.objects[0].fused.eyes == EyesUsed::kBoth;
    });
    for (int v : sfound) stereo_found[which] += v;
    set(kStereo, 1000.0 * frames / swall);
    probe_after[which] = probe(threads);
    cv::setNumThreads(saved_threads);
  }

  std::printf("bench_sift: %d frames 640x480 (%d for per-frame medians), %d threads, texture %s; "
              "fast kernels: %s; load average before %s, after %s (wall-clock rows need an idle machine)\n",
              frames, sample, threads, texture.c_str(), siftIsaName(bestSiftIsa()), load_before.c_str(),
              loadAverage().c_str());
  std::printf("features per frame: cv::SIFT %.0f, fast %.0f; detections found (of %d): cv::SIFT %d, "
              "fast %d; stereo found in both eyes (of %d): cv::SIFT %d, fast %d; re-detections found "
              "(of %d): cv::SIFT %d, fast %d\n\n",
              features[0] / static_cast<double>(sample), features[1] / static_cast<double>(sample), sample,
              found[0], found[1], frames, stereo_found[0], stereo_found[1], sample, roi_found[0], roi_found[1]);
  std::printf("| %-36s | %10s | %10s | %7s | %-8s | %s |\n", "row (N = --threads)", "cv::SIFT", "fast",
              "speed-up", "unit", "paper (Core2Duo + GeForce 8600M GT)");
  std::printf("|---|---|---|---|---|---|\n");
  for (const Row& r : rows) {
    const bool per_s = std::strcmp(r.unit, "ms") != 0;
    const double up = per_s ? r.fast / r.opencv : r.opencv / r.fast;
    std::printf("| %-36s | %10.2f | %10.2f | %6.2fx | %-8s | %s |\n", r.name, r.opencv, r.fast, up, r.unit,
                r.paper);
  }
  std::printf("\nROI extraction: the target's bounding box + 16 px (median %.0f %% of the frame), keypoint sizes "
              "2-40 px; ROI re-detection: Detector::detect with the true pose as the prior (its region: median "
              "%.0f %% of the frame, keypoint sizes %.1f-%.1f px)\n",
              median(roi_area), median(redetect_area), median(redetect_min), median(redetect_max));
  if (!stage[0].empty()) {
    std::printf("fast extractor, 1 thread, stage medians (thread CPU time, ms): scale space (pyramid + DoG + "
                "extremum test) %.2f | localisation %.2f | gradients + orientation + descriptors %.2f | sort + "
                "output %.2f | candidates %.0f\n",
                median(stage[0]), median(stage[1]), median(stage[2]), median(stage[3]), median(stage[4]));
  }
  if (!part[0].empty())
    std::printf("fast extractor, whole detection, 1 thread, stage medians (wall, ms): extraction %.2f | matching "
                "%.2f | pose + checks %.2f | rest %.2f\n",
                median(part[0]), median(part[1]), median(part[2]), median(part[3]));
  if (!roi_part[0].empty())
    std::printf("fast extractor, ROI re-detection, 1 thread, stage medians (wall, ms): extraction %.2f | "
                "matching %.2f | pose + checks %.2f | rest %.2f\n",
                median(roi_part[0]), median(roi_part[1]), median(roi_part[2]), median(roi_part[3]));
  std::printf("CPU-time bounds on --threads cores (1 thread per frame or pair, thread CPU time): mono stream "
              "cv::SIFT %.1f fps, fast %.1f fps; stereo cv::SIFT %.1f pairs/s, fast %.1f pairs/s\n",
              threads * 1000.0 / rows[kDetect1Cpu].opencv, threads * 1000.0 / rows[kDetect1Cpu].fast,
              threads * 1000.0 / rows[kStereoCpu].opencv, threads * 1000.0 / rows[kStereoCpu].fast);
  // The probe's fastest time over the run, and how much slower it ran around the streams.
  double best = INFINITY;
  for (int k = 0; k < 2; ++k)
    for (const Probe& p : {probe_before[k], probe_after[k]})
      for (double v : {p.alone, p.together})
        if (std::isfinite(v)) best = std::min(best, v);
  auto showProbe = [&](const char* name, int k) {
    if (!std::isfinite(probe_before[k].alone)) return;
    const Probe& b = probe_before[k];
    const Probe& a = probe_after[k];
    std::printf("machine probe (a fixed register-only multiply-add loop, ms, and x its fastest in this run) "
                "around the %s stream rows: before: alone %.0f (%.2fx), %d at once %.0f (%.2fx); after: alone "
                "%.0f (%.2fx), %d at once %.0f (%.2fx)\n",
                name, b.alone, b.alone / best, threads, b.together, b.together / best, a.alone, a.alone / best,
                threads, a.together, a.together / best);
  };
  showProbe("cv::SIFT", 0);
  showProbe("fast", 1);
  const double fps = rows[kStream].fast, latency = rows[kStreamLatency].fast;
  const double pairs = rows[kStereo].fast, roi = rows[kRoiDetect].fast;
  auto met = [](bool ok) { return ok ? "MET" : "NOT MET"; };
  std::printf("\ntarget (fast, wall clock): >= 48 fps mono stream: %s (%.1f fps); latency < 40 ms: %s (%.1f ms); "
              "stereo >= 24 pairs/s: %s (%.1f); ROI re-detection < 10 ms: %s (%.1f ms)\n",
              met(fps >= 48), fps, met(latency < 40), latency, met(pairs >= 24), pairs, met(roi < 10), roi);
  std::printf("target (fast, CPU-time bounds): mono %s (%.1f fps), latency %s (%.1f ms of CPU per frame), "
              "stereo %s (%.1f pairs/s), ROI re-detection %s (%.1f ms of CPU)\n",
              met(threads * 1000.0 / rows[kDetect1Cpu].fast >= 48), threads * 1000.0 / rows[kDetect1Cpu].fast,
              met(rows[kDetect1Cpu].fast < 40), rows[kDetect1Cpu].fast,
              met(threads * 1000.0 / rows[kStereoCpu].fast >= 24), threads * 1000.0 / rows[kStereoCpu].fast,
              met(rows[kRoiDetectCpu].fast < 10), rows[kRoiDetectCpu].fast);
  std::printf("bench_sift ran in %.0f s (rendering included)\n",
              std::chrono::duration<double>(Clock::now() - run_start).count());
  return 0;
}
catch (const std::exception& e) {  // a missing or unreadable input: one line, not an abort
  std::fprintf(stderr, "bench_sift: %s\n", e.what());
  return 1;
}
