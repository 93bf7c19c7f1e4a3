// Image folders (sorted, stamps files), stereo folder pairs, video files, webcams: frames, stamps
// and the one-line errors for bad input.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <chrono>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include "core/error.h"
#include "files_test_util.h"
#include "robot/files/image_sources.h"

namespace fs = std::filesystem;
using namespace refgrasp;
using namespace refgrasp::testing_util;
using robot::ReturnType;

namespace {

// Writes n images "img_<i>.png" (value 10 * i) of w x h into dir; returns them.
std::vector<cv::Mat> writeImages(const fs::path& dir, int n, int w = 32, int h = 24,
                                 const std::string& prefix = "img_") {
  fs::create_directories(dir);
  std::vector<cv::Mat> out;
  for (int i = 0; i < n; ++i) {
    cv::Mat m(h, w, CV_8UC1, cv::Scalar(10 * i));
    m.at<uchar>(0, 0) = 255;
    cv::imwrite((dir / (prefix + std::to_string(i) + ".png")).string(), m);
    out.push_back(m);
  }
  return out;
}

template <class F>
std::string configErrorOf(F f) {
  try {
    f();
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST(ImageFolder, SortedImagesWithStampsFromTheFrameRate) {
  const fs::path d = testDir();
  const auto imgs = writeImages(d, 3);
  std::ofstream(d / "notes.txt") << "not an image";
  files::FolderOptions o;
  o.fps_hz = 10;
  auto src = files::makeFolderSource(d.string(), smallCamera(32, 24), o);
  for (int i = 0; i < 3; ++i) {
    std::optional<robot::MonoFrame> f;
    ASSERT_EQ(src->grab(0, &f), ReturnType::kOk) << src->lastError();
    EXPECT_TRUE(identical(f->image, imgs[static_cast<size_t>(i)]));
    EXPECT_DOUBLE_EQ(f->stamp, 0.1 * i);
    EXPECT_EQ(f->index, i);
  }
  std::optional<robot::MonoFrame> f;
  EXPECT_EQ(src->grab(0, &f), ReturnType::kDeactivate);
}

TEST(ImageFolder, StampsFileOneStampPerImageOrTumStampAndFile) {
  const fs::path d = testDir();
  writeImages(d, 3);
  std::ofstream(d / "stamps.txt") << "# seconds\n1.5\n\n1.75\n2.0\n";
  const files::ImageList a = files::listImages(d.string(), {});
  ASSERT_EQ(a.stamps.size(), 3u);
  EXPECT_DOUBLE_EQ(a.stamps[1], 1.75);
  EXPECT_EQ(a.stamps_file, (d / "stamps.txt").string());
  // TUM rgb.txt layout: the file lists the images (here in another order and a subset).
  const fs::path tum = d / "rgb.txt";
  std::ofstream(tum) << "# timestamp filename\n1305031102.175304 img_2.png\n1305031102.211214 img_0.png\n";
  files::FolderOptions o;
  o.stamps_file = tum.string();
  const files::ImageList b = files::listImages(d.string(), o);
  ASSERT_EQ(b.files.size(), 2u);
  EXPECT_EQ(fs::path(b.files[0]).filename(), "img_2.png");
  EXPECT_DOUBLE_EQ(b.stamps[1], 1305031102.211214);
}

TEST(ImageFolder, BadFoldersAndStampsAreOneLineErrors) {
  const fs::path d = testDir();
  EXPECT_EQ(configErrorOf([&] { files::listImages((d / "none").string(), {}); }),
            (d / "none").string() + ": no such folder");
  fs::create_directories(d);
  EXPECT_EQ(configErrorOf([&] { files::listImages(d.string(), {}); }),
            d.string() + ": no image files in the folder: nothing to do");
  writeImages(d, 3);
  const auto stampsError = [&](const std::string& text) {
    std::ofstream(d / "stamps.txt") << text;
    return configErrorOf([&] { files::listImages(d.string(), {}); });
  };
  const std::string s = (d / "stamps.txt").string();
  EXPECT_EQ(stampsError("0.1\nzero\n0.3\n"), s + ": line 2: 'zero' is not a time stamp (seconds)");
  EXPECT_EQ(stampsError("0.1\n0.3\n0.2\n"), s + ": line 3: stamps must increase");
  EXPECT_EQ(stampsError("0.1\n0.2\n"), s + ": 2 stamps for 3 images in " + d.string());
  EXPECT_EQ(stampsError("0.1 img_0.png\n0.2 gone.png\n"),
            s + ": line 2: " + (d / "gone.png").string() + ": no such file");
  EXPECT_EQ(stampsError("0.1 img_0.png\n0.2\n"), s + ": line 2: mixes 'STAMP' and 'STAMP FILE' lines");
}

// Memory bombs: a stamps file is bounded by its size before it is read, and by its
// line length as it is read (core/file.h forEachLine); sparse files make them cheap.
TEST(ImageFolder, StampsFileBombsAreOneLineErrorsInBoundedTime) {
  const fs::path d = testDir();
  writeImages(d, 3);
  const std::string s = (d / "stamps.txt").string();
  const auto timedError = [&](double* seconds) {
    const auto t0 = std::chrono::steady_clock::now();
    const std::string e = configErrorOf([&] { files::listImages(d.string(), {}); });
    *seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    EXPECT_EQ(e.find('\n'), std::string::npos) << e;
    return e;
  };
  double t = 0;
  // Three stamps, then 4 GiB of NUL bytes: stopped at line 4, not read.
  std::ofstream(s) << "0.1\n0.2\n0.3\n";
  fs::resize_file(s, fs::file_size(s) + (uintmax_t{4} << 30));
  EXPECT_EQ(timedError(&t), s + ": is 4294967308 bytes, more than the limit of 1073741824");
  EXPECT_LT(t, 0.5);
  fs::resize_file(s, uintmax_t{512} << 20);  // under the size limit: the line limit stops it
  EXPECT_EQ(timedError(&t), s + ": line 4: longer than the limit of 65536 bytes");
  EXPECT_LT(t, 2.0);
  // A long line of digits without '\n'.
  std::ofstream(s) << "0.1\n" << std::string(1 << 20, '3');
  EXPECT_EQ(timedError(&t), s + ": line 2: longer than the limit of 65536 bytes");
  // A FIFO given as the stamps file: refused, no hang.
  const fs::path fifo = d / "pipe.txt";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  fs::remove(s);
  files::FolderOptions o;
  o.stamps_file = fifo.string();
  EXPECT_EQ(configErrorOf([&] { files::listImages(d.string(), o); }),
            fifo.string() + ": is a FIFO, not a regular file");
}

TEST(ImageFolder, AFrameOfTheWrongSizeIsAnErrorAndTheNextFrameIsRead) {
  const fs::path d = testDir();
  writeImages(d, 3);
  cv::imwrite((d / "img_1.png").string(), cv::Mat(12, 16, CV_8UC1, cv::Scalar(0)));
  std::ofstream(d / "img_3.png") << "not a png";
  auto src = files::makeFolderSource(d.string(), smallCamera(32, 24));
  std::optional<robot::MonoFrame> f;
  EXPECT_EQ(src->grab(0, &f), ReturnType::kOk);
  EXPECT_EQ(src->grab(0, &f), ReturnType::kError);
  EXPECT_FALSE(f.has_value());
  EXPECT_EQ(src->lastError(), (d / "img_1.png").string() + ": image is 16x12, the calibration is 32x24");
  EXPECT_EQ(src->grab(0, &f), ReturnType::kOk);
  EXPECT_EQ(f->index, 2);
  EXPECT_EQ(src->grab(0, &f), ReturnType::kError);
  EXPECT_EQ(src->lastError(),
            (d / "img_3.png").string() + ": not an image in a supported format (PNG, JPEG, BMP, PNM, TIFF, WebP)");
  EXPECT_EQ(src->grab(0, &f), ReturnType::kDeactivate);
}

TEST(StereoFolders, PairsByPositionAndMismatchedStampsAreOneLineErrors) {
  const fs::path d = testDir();
  writeImages(d / "left", 3);
  writeImages(d / "right", 3);
  std::ofstream(d / "left/stamps.txt") << "1.000\n1.100\n1.200\n";
  std::ofstream(d / "right/stamps.txt") << "1.0002\n1.140\n1.200\n";
  auto src = files::makeStereoFolderSource((d / "left").string(), (d / "right").string(),
                                           smallRig(32, 24));
  std::optional<robot::StereoFrame> f;
  ASSERT_EQ(src->grab(0, &f), ReturnType::kOk) << src->lastError();
  EXPECT_DOUBLE_EQ(f->stamp, 1.0);  // left stamp; 0.2 ms skew is within the 1 ms default
  EXPECT_EQ(src->grab(0, &f), ReturnType::kError);
  EXPECT_EQ(src->lastError(), (d / "right/img_1.png").string() +
                                  ": pair 1: stamps differ by 40.000 ms (left 1.100000 s, right "
                                  "1.140000 s; max 1.000 ms)");
  ASSERT_EQ(src->grab(0, &f), ReturnType::kOk);
  EXPECT_EQ(f->index, 2);
  EXPECT_EQ(src->grab(0, &f), ReturnType::kDeactivate);
  writeImages(d / "right", 4);
  fs::remove(d / "right/stamps.txt");
  EXPECT_EQ(configErrorOf([&] {
              files::makeStereoFolderSource((d / "left").string(), (d / "right").string(),
                                            smallRig(32, 24));
            }),
            (d / "right").string() + ": 4 images, but " + (d / "left").string() + " has 3");
}

TEST(VideoFile, FramesAndStampsOfAVideoOpenCvWrote) {
  const fs::path d = testDir();
  fs::create_directories(d);
  const std::string path = (d / "clip.mp4").string();
  {
    cv::VideoWriter w(path, cv::CAP_FFMPEG, cv::VideoWriter::fourcc('m', 'p', '4', 'v'), 25,
                      cv::Size(64, 48));
    ASSERT_TRUE(w.isOpened());
    for (int i = 0; i < 5; ++i) w.write(cv::Mat(48, 64, CV_8UC3, cv::Scalar(40 * i, 40 * i, 40 * i)));
  }
  auto src = files::makeVideoSource(path, smallCamera(64, 48));
  for (int i = 0; i < 5; ++i) {
    std::optional<robot::MonoFrame> f;
    ASSERT_EQ(src->grab(0, &f), ReturnType::kOk) << i << ": " << src->lastError();
    EXPECT_NEAR(f->stamp, i / 25.0, 1e-3);
    EXPECT_NEAR(cv::mean(f->image)[0], 40 * i, 4.0);  // lossy codec
    EXPECT_EQ(f->index, i);
  }
  std::optional<robot::MonoFrame> f;
  EXPECT_EQ(src->grab(0, &f), ReturnType::kDeactivate);
  // A calibration of another size: every frame is an error naming the video and the frame.
  auto wrong = files::makeVideoSource(path, smallCamera(32, 24));
  EXPECT_EQ(wrong->grab(0, &f), ReturnType::kError);
  EXPECT_EQ(wrong->lastError(), path + ": frame 0: image is 64x48, the calibration is 32x24");
}

TEST(VideoFile, MissingAndUndecodableVideosAreOneLineErrors) {
  const fs::path d = testDir();
  fs::create_directories(d);
  EXPECT_EQ(configErrorOf([&] { files::makeVideoSource((d / "none.mp4").string(), smallCamera()); }),
            (d / "none.mp4").string() + ": no such file");
  std::ofstream(d / "garbage.mp4") << std::string(5000, 'x');
  const std::string e = configErrorOf([&] { files::makeVideoSource((d / "garbage.mp4").string(), smallCamera()); });
  EXPECT_EQ(e.rfind((d / "garbage.mp4").string() + ": cannot decode as a video", 0), 0u) << e;
  EXPECT_EQ(e.find('\n'), std::string::npos);
}

// "Nothing to do" is said: a video whose container declares no frame.
TEST(VideoFile, AVideoWithoutFramesSaysNothingToDo) {
  const fs::path d = testDir();
  fs::create_directories(d);
  const std::string path = (d / "empty.avi").string();
  {
    cv::VideoWriter w(path, cv::CAP_FFMPEG, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 10,
                      cv::Size(64, 48), false);
    ASSERT_TRUE(w.isOpened());
  }
  EXPECT_EQ(configErrorOf([&] { files::makeVideoSource(path, smallCamera(64, 48)); }),
            path + ": has no frames (an empty video): nothing to do");
}

TEST(Webcam, ADeviceThatDoesNotExistIsAOneLineError) {
  EXPECT_EQ(configErrorOf([] { files::makeWebcamSource("/dev/video_refgrasp_none", smallCamera()); }),
            "/dev/video_refgrasp_none: no such V4L2 device");
  EXPECT_EQ(configErrorOf([] { files::makeWebcamSource("97", smallCamera()); }),
            "/dev/video97: no such V4L2 device");
}
