#pragma once
// Offline and webcam frame sources through OpenCV: image folders, video files, V4L2/UVC webcams.
// Frames are 8-bit gray or BGR as the file holds them; every frame is checked against the
// calibration's size (a wrong-sized frame gives kError + lastError(), the next grab moves on).
//
// Image folder: the files with an image extension (png jpg jpeg bmp pgm ppm pnm tif tiff webp),
// sorted by name, or the list of a stamps file. Stamps file (DIR/stamps.txt unless another is
// given): '#' comments and blank lines ignored; either one stamp (seconds) per line for the sorted
// images, or "STAMP FILE" per line (the TUM RGB-D rgb.txt layout; FILE relative to the folder),
// which then lists the images. Without a stamps file frame i is at i / fps_hz.
//
// Stamps file limits, far above any real one (refused with one line before it is read, or at the
// line): a line is ~20-60 bytes ("1305031102.175304 rgb/1305031102.175304.png"), a day at 48 fps
// 4.1M lines (~250 MB); the file is at most 1 GiB, a line 64 KiB (a path is at most 4 KiB),
// 8388608 stamps (48 h at 48 fps).
//
// An input with nothing in it (a folder without images, a video without a frame) is a
// ConfigError ("... nothing to do"): a tool says so and exits 2 instead of succeeding.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/camera.h"
#include "robot/camera.h"

namespace refgrasp::files {

inline constexpr uint64_t kMaxStampsFileBytes = uint64_t{1} << 30;
inline constexpr uint64_t kMaxStampsLineBytes = uint64_t{64} << 10;
inline constexpr size_t kMaxStamps = size_t{8} << 20;

struct FolderOptions {
  std::string stamps_file;  ///< "" -> DIR/stamps.txt when it exists
  double fps_hz = 30;       ///< frame rate for stamps when there is no stamps file
  /// Stereo folders: largest |left stamp - right stamp| of a pair (seconds).
  double max_stamp_skew_s = 0.001;
  void check() const;
};

/// The images of a folder and their stamps.
struct ImageList {
  std::string dir;
  std::vector<std::string> files;  ///< full paths, in order
  std::vector<Seconds> stamps;     ///< one per file
  std::string stamps_file;         ///< the stamps file used ("" when stamps come from fps_hz)
};

/// Throws ConfigError "<path>: <problem>" (no such folder, no images, a bad stamps line, a listed
/// file that does not exist, stamps not increasing, as many stamps as images needed, a stamps file
/// over the limits above).
ImageList listImages(const std::string& dir, const FolderOptions& options);

/// Mono images of one folder.
std::unique_ptr<robot::FrameSource> makeFolderSource(const std::string& dir,
                                                     const Intrinsics& camera,
                                                     const FolderOptions& options = {});
/// Stereo pairs from two folders (the i-th image of each). Throws ConfigError when the folders
/// hold different numbers of images. A pair whose stamps differ by more than max_stamp_skew_s
/// gives kError with a one-line error naming both stamps.
std::unique_ptr<robot::StereoSource> makeStereoFolderSource(const std::string& left_dir,
                                                            const std::string& right_dir,
                                                            const StereoRig& rig,
                                                            const FolderOptions& options = {});

struct VideoOptions {
  double fps_hz = 0;  ///< > 0: stamps at i / fps_hz instead of the container's time stamps
  void check() const;
};

/// A video file (anything FFmpeg decodes). Stamps: the decoder's presentation time of each frame.
/// Throws ConfigError "<file>: <problem>" when the file is missing or no frame can be decoded.
std::unique_ptr<robot::FrameSource> makeVideoSource(const std::string& path,
                                                    const Intrinsics& camera,
                                                    const VideoOptions& options = {});

struct WebcamOptions {
  int width = 0, height = 0;  ///< requested capture size; 0 = the driver's
  double fps_hz = 0;          ///< requested frame rate; 0 = the driver's
  void check() const;
};

/// A V4L2 camera ("/dev/video0" or "0"). Live: grab() returns the next frame the driver delivers
/// (driver buffer of one frame, so it is the newest). Stamps: the driver's buffer time stamp
/// (CLOCK_MONOTONIC, start of the frame's transfer on UVC cameras), seconds. Throws ConfigError
/// when the device does not exist or does not deliver frames of the calibration's size.
std::unique_ptr<robot::FrameSource> makeWebcamSource(const std::string& device,
                                                     const Intrinsics& camera,
                                                     const WebcamOptions& options = {});

/// True for a file name with one of the image extensions above (case-insensitive).
bool hasImageExtension(const std::string& path);

}  // namespace refgrasp::files
