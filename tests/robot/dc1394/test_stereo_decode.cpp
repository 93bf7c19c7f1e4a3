// Bumblebee2 decoding on buffers built byte by byte: de-interlacing (which byte is which eye),
// Bayer demosaicing for each pattern (OpenCV's code and libdc1394's own decoder must agree),
// Point Grey registers, packet size <-> frame rate, capture stamps.
#include <dc1394/conversions.h>
#include <gtest/gtest.h>

#include <vector>

#include "robot/dc1394/stereo_decode.h"

using namespace refgrasp::dc1394;

namespace {

// A Format7 mode 3 buffer: pixel (r, c) carries right(r, c) in its first (even) byte and
// left(r, c) in its second byte, as a Bumblebee2 in little-endian mode sends it.
std::vector<uint8_t> interlaced(int w, int h, uint8_t (*left)(int, int), uint8_t (*right)(int, int)) {
  std::vector<uint8_t> raw(static_cast<size_t>(2 * w * h));
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      raw[static_cast<size_t>(2 * (r * w + c))] = right(r, c);
      raw[static_cast<size_t>(2 * (r * w + c) + 1)] = left(r, c);
    }
  return raw;
}

uint8_t leftValue(int r, int c) { return static_cast<uint8_t>(100 + 10 * r + c); }
uint8_t rightValue(int r, int c) { return static_cast<uint8_t>(10 * r + c); }

// Colour of the filter cell at (r, c): 0 = R, 1 = G, 2 = B.
int cellColour(ColorFilter f, int r, int c) {
  const char* tile = toString(f);  // "RGGB": row 0 = tile[0] tile[1], row 1 = tile[2] tile[3]
  const char ch = tile[2 * (r % 2) + (c % 2)];
  return ch == 'R' ? 0 : ch == 'G' ? 1 : 2;
}

}  // namespace

TEST(Deinterlace, EvenBytesAreTheRightEyeOddBytesTheLeft) {
  const int w = 6, h = 4;
  const std::vector<uint8_t> raw = interlaced(w, h, leftValue, rightValue);
  cv::Mat left, right;
  ASSERT_TRUE(deinterlaceStereo(raw.data(), raw.size(), w, h, true, &left, &right));
  ASSERT_EQ(left.size(), cv::Size(w, h));
  ASSERT_EQ(left.type(), CV_8UC1);
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      EXPECT_EQ(left.at<uint8_t>(r, c), leftValue(r, c)) << r << "," << c;
      EXPECT_EQ(right.at<uint8_t>(r, c), rightValue(r, c)) << r << "," << c;
    }
  // Big-endian transfers swap the bytes of each pixel, hence the eyes.
  cv::Mat l2, r2;
  ASSERT_TRUE(deinterlaceStereo(raw.data(), raw.size(), w, h, false, &l2, &r2));
  EXPECT_EQ(cv::norm(l2, right, cv::NORM_INF), 0);
  EXPECT_EQ(cv::norm(r2, left, cv::NORM_INF), 0);
  // A short buffer is refused.
  EXPECT_FALSE(deinterlaceStereo(raw.data(), raw.size() - 1, w, h, true, &left, &right));
}

TEST(Bayer, EachPatternDecodesAUniformColourExactlyWithOpenCvAndLibdc1394) {
  const int w = 16, h = 12;
  const uint8_t rgb[3] = {200, 100, 30};
  const std::pair<ColorFilter, dc1394color_filter_t> filters[] = {
      {ColorFilter::kRGGB, DC1394_COLOR_FILTER_RGGB},
      {ColorFilter::kGBRG, DC1394_COLOR_FILTER_GBRG},
      {ColorFilter::kGRBG, DC1394_COLOR_FILTER_GRBG},
      {ColorFilter::kBGGR, DC1394_COLOR_FILTER_BGGR}};
  for (const auto& [f, tile] : filters) {
    cv::Mat mosaic(h, w, CV_8UC1);
    for (int r = 0; r < h; ++r)
      for (int c = 0; c < w; ++c) mosaic.at<uint8_t>(r, c) = rgb[cellColour(f, r, c)];
    const cv::Mat bgr = demosaic(mosaic, f);
    ASSERT_EQ(bgr.type(), CV_8UC3);
    std::vector<uint8_t> dc(static_cast<size_t>(3 * w * h));
    ASSERT_EQ(dc1394_bayer_decoding_8bit(mosaic.data, dc.data(), w, h, tile,
                                         DC1394_BAYER_METHOD_BILINEAR),
              DC1394_SUCCESS);
    for (int r = 2; r < h - 2; ++r)
      for (int c = 2; c < w - 2; ++c) {
        const cv::Vec3b p = bgr.at<cv::Vec3b>(r, c);
        EXPECT_EQ(p[2], rgb[0]) << toString(f) << " R at " << r << "," << c;
        EXPECT_EQ(p[1], rgb[1]) << toString(f) << " G";
        EXPECT_EQ(p[0], rgb[2]) << toString(f) << " B";
        const size_t k = static_cast<size_t>(3 * (r * w + c));  // libdc1394 writes RGB
        EXPECT_EQ(dc[k], rgb[0]) << toString(f) << " libdc1394 R";
        EXPECT_EQ(dc[k + 1], rgb[1]) << toString(f) << " libdc1394 G";
        EXPECT_EQ(dc[k + 2], rgb[2]) << toString(f) << " libdc1394 B";
      }
  }
  EXPECT_EQ(bayerToBgrCode(ColorFilter::kNone), -1);
}

TEST(Bayer, TwoColourEdgesLandInTheSamePlaceWithOpenCvAndLibdc1394) {
  // Left half red, right half blue, on an RGGB mosaic: both decoders put the edge between
  // columns 7 and 8 (pixels two columns away from it are pure).
  const int w = 16, h = 8;
  cv::Mat mosaic(h, w, CV_8UC1);
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      const int ch = cellColour(ColorFilter::kRGGB, r, c);
      const bool red = c < 8;
      mosaic.at<uint8_t>(r, c) = ch == 1 ? 0 : (ch == 0) == red ? 250 : 0;
    }
  const cv::Mat bgr = demosaic(mosaic, ColorFilter::kRGGB);
  std::vector<uint8_t> dc(static_cast<size_t>(3 * w * h));
  dc1394_bayer_decoding_8bit(mosaic.data, dc.data(), w, h, DC1394_COLOR_FILTER_RGGB,
                             DC1394_BAYER_METHOD_BILINEAR);
  for (int r = 2; r < h - 2; ++r)
    for (int c : {2, 3, 4, 5, 10, 11, 12, 13}) {
      const bool red = c < 8;
      EXPECT_EQ(bgr.at<cv::Vec3b>(r, c)[2], red ? 250 : 0) << r << "," << c;
      EXPECT_EQ(bgr.at<cv::Vec3b>(r, c)[0], red ? 0 : 250) << r << "," << c;
      EXPECT_EQ(dc[static_cast<size_t>(3 * (r * w + c))], red ? 250 : 0) << r << "," << c;
      EXPECT_EQ(dc[static_cast<size_t>(3 * (r * w + c) + 2)], red ? 0 : 250) << r << "," << c;
    }
}

TEST(PointGreyRegisters, BayerTileSensorInfoAndByteOrder) {
  EXPECT_EQ(colorFilterFromRegister(0x52474742), ColorFilter::kRGGB);  // "RGGB"
  EXPECT_EQ(colorFilterFromRegister(0x47425247), ColorFilter::kGBRG);
  EXPECT_EQ(colorFilterFromRegister(0x47524247), ColorFilter::kGRBG);
  EXPECT_EQ(colorFilterFromRegister(0x42474752), ColorFilter::kBGGR);
  EXPECT_EQ(colorFilterFromRegister(0x59595959), ColorFilter::kNone);  // "YYYY": mono
  EXPECT_EQ(colorFilterFromRegister(0x12345678), ColorFilter::kNone);
  const auto bb2_colour = sensorInfoFromRegister(0x0000000A);
  ASSERT_TRUE(bb2_colour.has_value());
  EXPECT_TRUE(bb2_colour->colour);
  EXPECT_EQ(bb2_colour->width, 640);
  EXPECT_EQ(bb2_colour->height, 480);
  const auto xga_mono = sensorInfoFromRegister(0x1234567D);  // only the low nibble counts
  ASSERT_TRUE(xga_mono.has_value());
  EXPECT_FALSE(xga_mono->colour);
  EXPECT_EQ(xga_mono->width, 1024);
  EXPECT_FALSE(sensorInfoFromRegister(0x3).has_value());
  EXPECT_EQ(kPgrLittleEndian, 0x80000000u);
}

TEST(Format7, PacketSizeForAFrameRateAndBack) {
  // 640x480 x 2 bytes = 614400 bytes per frame.
  EXPECT_EQ(packetBytesForFrameRate(640, 480, 2, 20, 4, 4096), 1536u);  // 400 cycles
  EXPECT_DOUBLE_EQ(frameRateForPacketBytes(640, 480, 2, 1536), 20.0);
  const uint32_t p48 = packetBytesForFrameRate(640, 480, 2, 48, 4, 4096);
  EXPECT_EQ(p48, 3704u);  // 614400 / 166 cycles = 3701.2 -> next multiple of 4
  EXPECT_GE(frameRateForPacketBytes(640, 480, 2, p48), 48.0);
  EXPECT_LT(frameRateForPacketBytes(640, 480, 2, p48), 48.5);
  // Clamped to what the camera allows.
  EXPECT_EQ(packetBytesForFrameRate(640, 480, 2, 200, 4, 4096), 4096u);
  EXPECT_EQ(packetBytesForFrameRate(640, 480, 2, 0.01, 8, 4096), 8u);
}

TEST(Format7, ExposureCentreFromTheDmaStamp) {
  // DMA done at 1000.0 s; 400 packets = 50 ms on the bus; 10 ms shutter -> centre 5 ms earlier.
  EXPECT_NEAR(exposureCentre(1000000000ull, 400, 0.010), 1000.0 - 0.050 - 0.005, 1e-9);
  EXPECT_NEAR(exposureCentre(2500000ull, 0, 0), 2.5, 1e-12);
}
