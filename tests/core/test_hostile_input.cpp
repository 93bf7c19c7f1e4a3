// Hostile input to the shared readers: files that are not regular files, YAML that
// yaml-cpp accepts silently (a key twice, aliases, typos), camera files that half-parse, and
// images that are bombs, truncated or corrupt. Each gives ONE line naming the file and the
// problem, never a hang, a crash or a decoder's own message on stderr.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <random>

#include "common/hostile.h"
#include "common/temp_dir.h"
#include "core/camera.h"
#include "core/error.h"
#include "core/file.h"
#include "core/image_io.h"
#include "core/yaml.h"

using namespace refgrasp;
using refgrasp::testing::configErrorOf;
using refgrasp::testing::encodeImage;
using refgrasp::testing::pngDeclaring;
namespace fs = std::filesystem;

namespace {

fs::path dir() { return refgrasp::testing::tempDir("refgrasp_test_hostile"); }

std::string write(const std::string& name, const std::string& bytes) {
  const fs::path p = dir() / name;
  std::ofstream(p, std::ios::binary) << bytes;
  return p.string();
}

std::string yamlError(const std::string& text) {
  return configErrorOf([&] {
    const YamlFile f = YamlFile::fromText("f.yaml", text);
    f.rejectUnknownFields();
  });
}

}  // namespace

TEST(HostileFiles, FifoDirectoryAndDeviceAreOneLineErrorsNotHangs) {
  const std::string fifo = (dir() / "pipe.yaml").string();
  fs::remove(fifo);
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_EQ(configErrorOf([&] { YamlFile f(fifo); }), fifo + ": is a FIFO, not a regular file");
  EXPECT_EQ(configErrorOf([&] { loadCameraFile(fifo); }), fifo + ": is a FIFO, not a regular file");
  EXPECT_EQ(readImage(fifo, ImageMode::kGray).error, fifo + ": is a FIFO, not a regular file");
  EXPECT_EQ(configErrorOf([&] { YamlFile f(dir().string()); }),
            dir().string() + ": is a directory, expected a file");
  EXPECT_EQ(readImage("/dev/zero", ImageMode::kGray).error,
            "/dev/zero: is a character device, not a regular file");
  EXPECT_EQ(configErrorOf([&] { YamlFile f("/dev/null"); }),
            "/dev/null: is a character device, not a regular file");
  EXPECT_EQ(readImage((dir() / "none.png").string(), ImageMode::kGray).error,
            (dir() / "none.png").string() + ": file not found");
  // A config beyond the size cap is refused before parsing.
  const std::string big = write("big.yaml", std::string(kMaxConfigFileBytes + 1, '#'));
  EXPECT_NE(configErrorOf([&] { YamlFile f(big); }).find("more than the limit"), std::string::npos);
}

TEST(StrictYaml, AKeyGivenTwiceIsAnErrorAtEveryLevel) {
  EXPECT_EQ(yamlError("a: 1\nb: 2\na: 3\n"), "f.yaml: a: given twice (lines 1 and 3)");
  EXPECT_EQ(yamlError("m: {x: 1, x: 2}\n"), "f.yaml: m.x: given twice (lines 1 and 1)");
  EXPECT_EQ(yamlError("l:\n  - {k: 1}\n  - {k: 1, k: 2}\n"), "f.yaml: l[1].k: given twice (lines 3 and 3)");
  EXPECT_EQ(yamlError("o:\n  p:\n    t: 1\n    t: 2\n"), "f.yaml: o.p.t: given twice (lines 3 and 4)");
}

TEST(StrictYaml, AliasesComplexKeysAndSecondDocumentsAreRefused) {
  EXPECT_EQ(yamlError("a: &x [1, 2]\nb: *x\n"), "f.yaml: line 2: aliases (*name) are not supported");
  EXPECT_EQ(yamlError("? [1, 2]\n: 3\n"), "f.yaml: line 1: a key must be a plain name");
  EXPECT_EQ(yamlError("a: 1\n---\nb: 2\n"), "f.yaml: more than one YAML document (---)");
  EXPECT_NE(yamlError("a: [\n").find("f.yaml: invalid YAML at line"), std::string::npos);
  EXPECT_EQ(yamlError("- 1\n"), "f.yaml: expected a YAML mapping at the top level");
  // Deep nesting is an error (yaml-cpp's depth guard, or ours on the keys), not a stack overflow.
  EXPECT_EQ(yamlError("a: " + std::string(100000, '[')), "f.yaml: a[0]: line 1: a key must be a plain name");
  std::string maps;
  for (int i = 0; i < 100000; ++i) maps += "{a: ";
  EXPECT_NE(yamlError("a: " + maps).find("f.yaml: invalid YAML at line 1"), std::string::npos);
}

TEST(StrictYaml, UnknownFieldsSuggestTheNearestKnownOne) {
  EXPECT_EQ(didYouMean("referance_pose", {"reference_pose", "reference_image"}),
            " (did you mean reference_pose?)");
  EXPECT_EQ(didYouMean("pattern_regoin", {"pattern_region", "pattern_plane"}),
            " (did you mean pattern_region?)");
  EXPECT_EQ(didYouMean("watchdog_periode_s", {"watchdog_period_s", "control_period_s"}),
            " (did you mean watchdog_period_s?)");
  EXPECT_EQ(didYouMean("frame_rate", {"frame_rate_hz", "gain_db"}), " (did you mean frame_rate_hz?)");
  EXPECT_EQ(didYouMean("colour", {"reference_pose", "camera"}), "");
  const YamlFile f = YamlFile::fromText("f.yaml", "camera: x\nreferance_pose: {}\n");
  EXPECT_EQ(configErrorOf([&] { f.onlyKeys(f.root(), "", {"camera", "reference_pose"}); }),
            "f.yaml: referance_pose: unknown field (did you mean reference_pose?)");
  // rejectUnknownFields: every key no accessor looked up, at any depth.
  const YamlFile g = YamlFile::fromText("g.yaml", "head:\n  pan: {min_rad: 0, max_rad: 1, max_sped: 2}\n");
  g.number(g.root(), "head.pan.min_rad");
  g.number(g.root(), "head.pan.max_rad");
  g.number(g.root(), "head.pan.max_speed", 1.0);
  EXPECT_EQ(configErrorOf([&] { g.rejectUnknownFields(); }),
            "g.yaml: head.pan.max_sped: unknown field (did you mean max_speed?)");
}

TEST(StrictYaml, WrongTypesNameTheField) {
  const YamlFile f = YamlFile::fromText(
      "f.yaml", "s: [1]\nn: {a: 1}\nb: maybe\np: 3\nq: {translation: [0, 0, 1], rotaton_vector: [0, 0, 0]}\n"
                "v: [1, .nan, 2]\nx: .inf\n");
  EXPECT_EQ(configErrorOf([&] { f.string(f.root(), "s"); }), "f.yaml: s: expected a string");
  EXPECT_EQ(configErrorOf([&] { f.number(f.root(), "n"); }), "f.yaml: n: expected a number");
  EXPECT_EQ(configErrorOf([&] { f.boolean(f.root(), "b", false); }), "f.yaml: b: expected true or false");
  EXPECT_EQ(configErrorOf([&] { f.number(f.root(), "p.offset"); }), "f.yaml: p: expected a mapping");
  EXPECT_EQ(configErrorOf([&] { f.pose(f.root(), "q"); }),
            "f.yaml: q.rotaton_vector: unknown field (did you mean rotation_vector?)");
  EXPECT_EQ(configErrorOf([&] { f.numbers(f.root(), "v"); }), "f.yaml: v: element 1 is not finite");
  EXPECT_EQ(configErrorOf([&] { f.number(f.root(), "x"); }), "f.yaml: x: must be finite");
}

TEST(StrictYaml, ErrorsStayOneLineWhateverTheKey) {
  const std::string e = yamlError("\"bad\\nkey\": 1\n\"bad\\nkey\": 2\n");
  EXPECT_EQ(e, "f.yaml: bad\\nkey: given twice (lines 1 and 2)");
  EXPECT_EQ(oneLine(std::string(5000, 'k')).size(), 300u);
  EXPECT_EQ(oneLine(oneLine("a\tb\x01")), "a\\tb\\x01");
}

TEST(CameraFileStrict, AMatrixThatIsNotRowMajorUpperTriangularIsAnError) {
  const auto cam = [](const std::string& K, const std::string& extra = "") {
    return write("k.yaml", "image_width: 640\nimage_height: 480\ncamera_matrix: {rows: 3, cols: 3, data: [" +
                               K + "]}\n" + extra);
  };
  EXPECT_NO_THROW(loadCameraFile(cam("550, 0, 320, 0, 550, 240, 0, 0, 1")));
  // Column-major: the principal point lands in the last row.
  EXPECT_NE(configErrorOf([&] { loadCameraFile(cam("550, 0, 0, 0, 550, 0, 320, 240, 1")); })
                .find("camera_matrix.data: not [fx, 0, cx, 0, fy, cy, 0, 0, 1]"),
            std::string::npos);
  EXPECT_NE(configErrorOf([&] { loadCameraFile(cam("550, 0, 320, 0, 550, 240, 0, 0, 2")); })
                .find("last row 0 0 1"),
            std::string::npos);
  EXPECT_NE(configErrorOf([&] { loadCameraFile(cam("550, 3, 320, 0, 550, 240, 0, 0, 1")); }).find("skew"),
            std::string::npos);
  const std::string p = cam("550, 0, 320, 0, 550, 240, 0, 0, 1");
  EXPECT_EQ(configErrorOf([&] {
              loadCameraFile(write("t.yaml", "image_width: 640\nimage_height: 480\ncamera_matirx: {data: []}\n"));
            }),
            (dir() / "t.yaml").string() + ": camera_matirx: unknown field (did you mean camera_matrix?)");
  EXPECT_EQ(configErrorOf([&] {
              loadCameraFile(write("r.yaml", "image_width: 640\nimage_height: 480\n"
                                             "camera_matrix: {rows: 3, cols: 4, data: [550, 0, 320, 0, 550, 240, 0, 0, 1]}\n"));
            }),
            (dir() / "r.yaml").string() + ": camera_matrix: rows x cols (3 x 4) differs from the 9 numbers of data");
  EXPECT_NE(configErrorOf([&] {
              loadCameraFile(write("d.yaml", "image_width: 640\nimage_height: 480\nimage_width: 320\n"));
            }).find("image_width: given twice (lines 1 and 3)"),
            std::string::npos);
  EXPECT_NE(configErrorOf([&] {
              loadCameraFile(write("huge.yaml", "image_width: 100000\nimage_height: 100000\n"
                                                "camera_matrix: {data: [550, 0, 320, 0, 550, 240, 0, 0, 1]}\n"));
            }).find("100000x100000 is more than the"),
            std::string::npos);
}

TEST(CameraFileStrict, VispXmlIsReadStrictlyWithoutRegexRecursion) {
  const std::string head = "<?xml version=\"1.0\"?>\n<root>\n<!-- c -->\n<camera><name>c</name>"
                           "<image_width>640</image_width><image_height>480</image_height>\n";
  const std::string model = "<model><type>perspectiveProjWithoutDistortion</type><px>550</px><py>550</py>"
                            "<u0>320</u0><v0>240</v0></model>";
  EXPECT_NO_THROW(loadCameraFile(write("ok.xml", head + model + "</camera></root>\n")));
  const auto err = [&](const std::string& name, const std::string& text) {
    return configErrorOf([&] { loadCameraFile(write(name, text)); });
  };
  const std::string typo = (dir() / "typo.xml").string();
  EXPECT_EQ(err("typo.xml", head + "<imge_height>3</imge_height>" + model + "</camera></root>"),
            typo + ": camera.imge_height: unknown element (did you mean image_height?)");
  EXPECT_NE(err("twice.xml", head + "<image_width>320</image_width>" + model + "</camera></root>")
                .find("camera.image_width: given twice"),
            std::string::npos);
  EXPECT_NE(err("attr.xml", head + "<model a=\"1\"></model></camera></root>").find("attributes are not supported"),
            std::string::npos);
  EXPECT_NE(err("open.xml", head + model).find("is not closed"), std::string::npos);
  EXPECT_NE(err("cross.xml", head + model + "</root></camera>").find("</root> closes <camera>"), std::string::npos);
  EXPECT_NE(err("deep.xml", std::string(100000, '<') ).find("line 1"), std::string::npos);
  std::string nested;
  for (int i = 0; i < 50; ++i) nested += "<a>";
  EXPECT_NE(err("nest.xml", nested).find("nested deeper than 16"), std::string::npos);
  // A long text is read without recursion (a std::regex reader recurses once per character:
  // a stack overflow).
  EXPECT_NE(err("long.xml", head + "<model><type>" + std::string(2000000, 'x') + "</type></model></camera></root>")
                .find("unsupported projection model"),
            std::string::npos);
}

TEST(ImageInput, ABombIsRefusedFromItsHeaderBeforeDecoding) {
  const std::string bomb = write("bomb.png", pngDeclaring(20000, 20000));
  const ImageRead r = readImage(bomb, ImageMode::kGray);
  EXPECT_TRUE(r.image.empty());
  EXPECT_EQ(r.error, bomb + ": PNG declares 20000x20000 pixels, more than the limit of 33554432 pixels "
                            "(REFGRASP_MAX_IMAGE_PIXELS)");
  // The limit is configurable, per call and by the environment.
  std::mt19937_64 rng(199);
  const std::string small = write("small.png", encodeImage(".png", refgrasp::testing::noiseImage(rng, 20, 10)));
  EXPECT_TRUE(readImage(small, ImageMode::kGray, {200}).ok());
  EXPECT_NE(readImage(small, ImageMode::kGray, {199}).error.find("20x10 pixels, more than the limit of 199"),
            std::string::npos);
  ::setenv("REFGRASP_MAX_IMAGE_PIXELS", "150", 1);
  EXPECT_EQ(ImageLimits::fromEnvironment().max_pixels, 150);
  EXPECT_FALSE(readImage(small, ImageMode::kGray).ok());
  ::unsetenv("REFGRASP_MAX_IMAGE_PIXELS");
  EXPECT_TRUE(readImage(small, ImageMode::kGray).ok());
}

TEST(ImageInput, EveryFormatsHeaderGivesItsSize) {
  std::mt19937_64 rng(211);
  const cv::Mat img = refgrasp::testing::noiseImage(rng, 37, 23);
  cv::Mat bgr;
  cv::merge(std::vector<cv::Mat>{img, img, img}, bgr);
  for (const char* ext : {".png", ".jpg", ".bmp", ".pgm", ".ppm", ".tif", ".webp"}) {
    const std::string bytes = encodeImage(ext, std::string(ext) == ".ppm" ? bgr : img);
    ImageHeader h;
    EXPECT_EQ(probeImageHeader(bytes, &h), "") << ext;
    EXPECT_EQ(h.width, 37) << ext;
    EXPECT_EQ(h.height, 23) << ext;
    const ImageRead r = decodeImage(std::string("x") + ext, bytes, ImageMode::kGray);
    EXPECT_TRUE(r.ok()) << r.error;
    EXPECT_EQ(r.image.size(), cv::Size(37, 23)) << ext;
  }
  ImageHeader h;
  EXPECT_EQ(probeImageHeader("GIF89a....", &h),
            "not an image in a supported format (PNG, JPEG, BMP, PNM, TIFF, WebP)");
  EXPECT_EQ(probeImageHeader("", &h), "empty file, not an image");
  EXPECT_EQ(probeImageHeader("P5\n# comment\n0 10\n255\n", &h), "PNM header declares an empty image (0x10)");
}

TEST(ImageInput, TruncatedAndCorruptImagesSayWhatAndDecodersStayQuiet) {
  std::mt19937_64 rng(232);
  const std::string png = encodeImage(".png", refgrasp::testing::noiseImage(rng, 64, 48));
  const std::string jpg = encodeImage(".jpg", refgrasp::testing::noiseImage(rng, 64, 48));
  ::testing::internal::CaptureStderr();
  const ImageRead tp = decodeImage("t.png", png.substr(0, png.size() / 2), ImageMode::kGray);
  const ImageRead tj = decodeImage("t.jpg", jpg.substr(0, jpg.size() / 2), ImageMode::kGray);
  // libjpeg warns ("3 extraneous bytes before marker 0xdb": garbage after the APP0 segment) and
  // decodes: that is a corrupt file.
  const ImageRead cj = decodeImage("c.jpg", refgrasp::testing::corruptJpeg(jpg), ImageMode::kGray);
  std::string crc = png;
  crc[40] ^= 0x55;  // inside IDAT: libpng's CRC check fails
  const ImageRead cp = decodeImage("c.png", crc, ImageMode::kGray);
  const std::string stderr_text = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(stderr_text, "") << "a decoder wrote to stderr";
  EXPECT_EQ(tp.error, "t.png: truncated PNG (the file ends before its IEND chunk)");
  EXPECT_EQ(tj.error, "t.jpg: truncated JPEG (no end-of-image marker)");
  EXPECT_TRUE(tj.image.empty());
  EXPECT_EQ(cj.error, "c.jpg: corrupt JPEG (Corrupt JPEG data: 3 extraneous bytes before marker 0xdb)")
      << cj.error;
  EXPECT_TRUE(cj.image.empty());
  EXPECT_EQ(cp.error.rfind("c.png: cannot decode the PNG image (corrupt) (libpng error:", 0), 0u) << cp.error;
  for (const ImageRead* r : {&tp, &tj, &cj, &cp}) EXPECT_EQ(r->error.find('\n'), std::string::npos);
}
