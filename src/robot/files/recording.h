#pragma once
// refgrasp recordings: a folder a person can open (public contract, docs/formats.md "Recording").
//
//   DIR/recording.json   {"format": "refgrasp-recording", "version": 1, "kind": "stereo"|"mono",
//                         "calibration": {"rig", "left", "right"} | {"camera"} (paths in DIR),
//                         "source", "created_by", "created_at"}
//   DIR/calib/           left.yaml right.yaml rig.yaml (stereo) | camera.yaml (mono):
//                        ROS camera_info YAML and the rig YAML of core/camera.h
//   DIR/frames/          NNNNNN_left.png NNNNNN_right.png (stereo) | NNNNNN.png (mono), lossless
//                        8-bit gray (or BGR) PNG; NNNNNN = "frame", 0-based, 6+ digits
//   DIR/index.jsonl      one JSON line per frame, in order:
//                        {"frame": 0, "index": 17, "stamp": 0.354,
//                         "files": {"left": "frames/000000_left.png", "right": ...} | {"image": ...},
//                         "capture": {"head": {"pan_rad", "tilt_rad"}, "bMc": POSE, "wMb_odom": POSE},
//                         "truth": [{"object": "tea_box", "cMo": POSE, "rMo": POSE}],  (when known)
//                         "robot": {RobotState fields} }                                (when known)
//                        POSE = {"R": [9, row-major], "t": [x, y, z]}, aMb, metres; stamp = exposure
//                        centre (s, on the source's clock); index = the device's frame counter.
//
// Crash safety: each image is written to a hidden temporary name, fsync'ed and renamed; only then
// is the frame's index line appended (one write) and flushed. A recorder killed at any instant, or
// a disk that fills, leaves an index that is valid up to the last complete frame (at worst a
// truncated last line). The reader reads a damaged recording up to its last good frame and says
// so in one warning.
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/camera.h"
#include "robot/camera.h"
#include "robot/hal.h"

namespace refgrasp::files {

inline constexpr const char* kRecordingFormat = "refgrasp-recording";
inline constexpr int kRecordingVersion = 1;

// Reader limits, far above any real recording; beyond them the reader refuses with one line
// before it allocates (docs/formats.md "Recording"). An index line of a stereo frame with
// capture state and ground truth is ~1 kB, with robot state ~2 kB (enon_grasp --log); 256
// objects of ground truth (the scenario limit) ~130 kB. The frame limit bounds the memory of the
// parsed entries (~1 kB each with their strings: ~1 GB at the limit) and allows 6 h at 48 fps;
// the size limit allows 2 kB lines at that count. recording.json is read as a configuration file
// (kMaxConfigFileBytes, 4 MiB; a real one is ~300 B).
inline constexpr uint64_t kMaxIndexLineBytes = uint64_t{1} << 20;  ///< 1 MiB a line
inline constexpr uint64_t kMaxIndexBytes = uint64_t{4} << 30;      ///< 4 GiB in all
inline constexpr size_t kMaxIndexFrames = size_t{1} << 20;         ///< 1048576 frames

struct RecordingOptions {
  std::string source;       ///< what was recorded (a source spec or a description)
  std::string created_by;   ///< tool name
  int png_compression = 1;  ///< 0..9; lossless at every level, 1 is fast
  /// fsync every image before it is renamed, the frames folder and the index after each frame:
  /// the recording then survives a power loss too, not only a killed process.
  bool fsync = true;
  void check() const;
};

struct WriteStatus {
  bool ok = true;
  std::string error;   ///< one line when !ok, naming the file
  bool fatal = false;  ///< an I/O failure: every later write fails (else only this frame was refused)
};

class RecordingWriter {
 public:
  /// Create DIR (it must not exist, or be an empty folder), calib/ and recording.json.
  /// Throws ConfigError "<path>: <problem>" (start-up).
  static std::unique_ptr<RecordingWriter> createStereo(const std::string& dir, const StereoRig& rig,
                                                       const RecordingOptions& options);
  static std::unique_ptr<RecordingWriter> createMono(const std::string& dir,
                                                     const Intrinsics& camera,
                                                     const RecordingOptions& options);
  ~RecordingWriter();
  RecordingWriter(const RecordingWriter&) = delete;
  RecordingWriter& operator=(const RecordingWriter&) = delete;

  /// Appends a frame (images of the calibration's size, CV_8UC1 or CV_8UC3). Never throws. After
  /// a failure (disk full, I/O error, wrong frame) the recording stays valid up to the previous
  /// frame; a failed image or index write makes every later write fail with the same error.
  /// \param robot the robot state at (or nearest to) the frame, when known.
  WriteStatus write(const robot::StereoFrame& frame, const robot::RobotState* robot = nullptr);
  WriteStatus write(const robot::MonoFrame& frame, const robot::RobotState* robot = nullptr);

  int64_t frames() const { return frames_; }
  const std::string& dir() const { return dir_; }
  bool stereo() const { return stereo_; }

 private:
  RecordingWriter(const std::string& dir, bool stereo, const RecordingOptions& options);
  /// Writes recording.json (calibration: key -> file in the recording) and opens the index.
  void start(const std::vector<std::pair<std::string, std::string>>& calibration);
  struct Image {
    const cv::Mat* image;
    const Intrinsics* camera;
    std::string file;  ///< relative to dir_
    const char* key;   ///< "left", "right" or "image"
  };
  WriteStatus append(const std::vector<Image>& images, int64_t index, Seconds stamp,
                     const robot::CaptureState& capture,
                     const std::vector<robot::ObjectTruth>& truth,
                     const robot::RobotState* robot);
  WriteStatus failed(const std::string& error);

  std::string dir_;
  bool stereo_;
  RecordingOptions opt_;
  StereoRig rig_;
  Intrinsics camera_;
  int index_fd_ = -1, frames_fd_ = -1;
  long long index_size_ = 0;  ///< bytes of complete lines
  int64_t frames_ = 0;
  std::string error_;  ///< sticky after an I/O failure
};

/// One index line, parsed.
struct IndexEntry {
  int64_t frame = 0;   ///< 0-based position in the recording
  int64_t index = 0;   ///< the device's frame counter
  Seconds stamp = 0;   ///< exposure centre
  std::vector<std::string> files;  ///< relative to the recording: {left, right} or {image}
  robot::CaptureState capture;
  std::vector<robot::ObjectTruth> truth;
  std::optional<robot::RobotState> robot;
};

/// A recording opened for reading.
class Recording {
 public:
  /// Reads recording.json, the calibration and the index up to the last good frame: a line that
  /// does not parse, a frame number out of order, or an image that is missing or truncated (no
  /// PNG end chunk) ends the recording there, with one warning (warning()). Throws ConfigError
  /// naming the file for a folder that is not a readable recording, an index over the limits
  /// above (its size; a line longer than kMaxIndexLineBytes or past kMaxIndexFrames, naming the
  /// line), and a recording
  /// without a frame to read ("no frames (an empty recording): nothing to do", or the first
  /// line's damage "; no frame before it: nothing to do").
  static Recording open(const std::string& dir);

  bool stereo() const { return stereo_; }
  const std::string& dir() const { return dir_; }
  const std::string& source() const { return source_; }
  /// Stereo recordings only.
  const StereoRig& rig() const { return rig_; }
  /// The mono camera, or the left eye of a stereo recording.
  const Intrinsics& camera() const { return stereo_ ? rig_.left : camera_; }
  /// Calibration file paths (absolute or relative to the working directory), as listed.
  const std::string& calibrationFile(const std::string& key) const;
  const std::vector<IndexEntry>& entries() const { return entries_; }
  /// "" when the recording is intact, else one line saying where and why it ends.
  const std::string& warning() const { return warning_; }

  /// Decodes the images of entries()[i]. False and a one-line error naming the file when an
  /// image cannot be decoded or its size differs from the calibration.
  bool read(size_t i, robot::StereoFrame* frame, std::string* error) const;
  /// A mono recording, or the left eye of a stereo one.
  bool read(size_t i, robot::MonoFrame* frame, std::string* error) const;

 private:
  /// recording.json and the calibration it names (stereo_, source_, rig_/camera_, calibration_).
  void readMeta(const std::string& meta_path);
  bool readImage(const std::string& rel, const Intrinsics& cam, cv::Mat* out,
                 std::string* error) const;

  std::string dir_, source_, warning_;
  bool stereo_ = false;
  StereoRig rig_;
  Intrinsics camera_;
  std::vector<std::pair<std::string, std::string>> calibration_;
  std::vector<IndexEntry> entries_;
};

/// Frame sources over a recording (offline: one frame per grab, kDeactivate at the end; a frame
/// that cannot be decoded gives kError with lastError() and the next grab moves on).
std::unique_ptr<robot::StereoSource> makeRecordingStereoSource(Recording recording);
/// A mono recording, or the left eye of a stereo recording.
std::unique_ptr<robot::FrameSource> makeRecordingMonoSource(Recording recording);

/// True when `dir` holds a recording.json.
bool isRecording(const std::string& dir);

}  // namespace refgrasp::files
