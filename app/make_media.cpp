// Writes the project's own grayscale PNG textures (targets, hard cases, backgrounds, clutter,
// box faces) with OpenCV drawing only. Deterministic: every texture has a fixed seed, so running
// it again reproduces media/ bit for bit (given the same OpenCV build).
#include <CLI/CLI.hpp>
#include <filesystem>
#include <functional>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <string>
#include <vector>

#include "core/error.h"
#include "tool/tool.h"

namespace {

using namespace refgrasp;
using Rng = std::mt19937_64;

double uni(Rng& rng, double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng); }
int uniInt(Rng& rng, int a, int b) { return std::uniform_int_distribution<int>(a, b)(rng); }
bool coin(Rng& rng, double p = 0.5) { return uni(rng, 0, 1) < p; }

/// Smooth random field in [0,1]: white noise on a grid `cell` pixels apart, bicubic upsampled.
cv::Mat noiseField(int w, int h, double cell, Rng& rng) {
  const int gw = std::max(2, static_cast<int>(w / cell) + 2);
  const int gh = std::max(2, static_cast<int>(h / cell) + 2);
  cv::Mat grid(gh, gw, CV_32F);
  for (int y = 0; y < gh; ++y)
    for (int x = 0; x < gw; ++x) grid.at<float>(y, x) = static_cast<float>(uni(rng, 0, 1));
  cv::Mat up;
  cv::resize(grid, up, cv::Size(static_cast<int>(gw * cell), static_cast<int>(gh * cell)), 0, 0,
             cv::INTER_CUBIC);
  return up(cv::Rect(0, 0, w, h)).clone();
}

/// Sum of noise fields at octaves from `coarse` down to `fine` pixels, normalised to [0,1].
cv::Mat fractalNoise(int w, int h, double coarse, double fine, Rng& rng) {
  cv::Mat acc = cv::Mat::zeros(h, w, CV_32F);
  double amp = 1.0;
  for (double cell = coarse; cell >= fine; cell /= 2, amp *= 0.55) acc += amp * noiseField(w, h, cell, rng);
  cv::normalize(acc, acc, 0, 1, cv::NORM_MINMAX);
  return acc;
}

cv::Mat linearGradient(int w, int h, Rng& rng) {
  const double a = uni(rng, 0, 2 * CV_PI);
  cv::Mat g(h, w, CV_32F);
  const double c = std::cos(a), s = std::sin(a), n = std::abs(c) * w + std::abs(s) * h;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      g.at<float>(y, x) = static_cast<float>(0.5 + ((x - w / 2.0) * c + (y - h / 2.0) * s) / n);
  return g;
}

cv::Mat toGray8(const cv::Mat& f01, double lo, double hi) {
  cv::Mat out;
  f01.convertTo(out, CV_8U, hi - lo, lo);
  return out;
}

/// A gray level that stands out against `bg` by at least `min_contrast`.
int contrasting(Rng& rng, int bg, int min_contrast = 60) {
  for (int i = 0; i < 20; ++i) {
    const int g = uniInt(rng, 0, 255);
    if (std::abs(g - bg) >= min_contrast) return g;
  }
  return bg < 128 ? 255 : 0;
}

int grayAt(const cv::Mat& img, cv::Point p) {
  p.x = std::clamp(p.x, 0, img.cols - 1);
  p.y = std::clamp(p.y, 0, img.rows - 1);
  return img.at<uchar>(p);
}

void drawShapes(cv::Mat& img, int n, int min_size, int max_size, Rng& rng) {
  for (int i = 0; i < n; ++i) {
    const cv::Point c(uniInt(rng, 0, img.cols - 1), uniInt(rng, 0, img.rows - 1));
    const int s = uniInt(rng, min_size, max_size);
    const cv::Scalar col(contrasting(rng, grayAt(img, c)));
    const int thick = coin(rng, 0.55) ? cv::FILLED : uniInt(rng, 1, std::max(1, s / 8));
    switch (uniInt(rng, 0, 4)) {
      case 0:
        cv::circle(img, c, s / 2, col, thick, cv::LINE_AA);
        break;
      case 1: {
        const cv::RotatedRect r(c, cv::Size2f(s, s * uni(rng, 0.3, 1.0)), uni(rng, 0, 180));
        cv::Point2f p[4];
        r.points(p);
        std::vector<cv::Point> poly(p, p + 4);
        if (thick == cv::FILLED)
          cv::fillConvexPoly(img, poly, col, cv::LINE_AA);
        else
          cv::polylines(img, poly, true, col, thick, cv::LINE_AA);
        break;
      }
      case 2:
        cv::ellipse(img, c, cv::Size(s / 2, static_cast<int>(s * uni(rng, 0.15, 0.5))),
                    uni(rng, 0, 180), 0, uni(rng, 180, 360), col, thick, cv::LINE_AA);
        break;
      case 3: {
        std::vector<cv::Point> poly;
        const int k = uniInt(rng, 3, 7);
        for (int j = 0; j < k; ++j) {
          const double a = 2 * CV_PI * j / k + uni(rng, -0.3, 0.3), r = s * uni(rng, 0.25, 0.6);
          poly.emplace_back(c.x + static_cast<int>(r * std::cos(a)), c.y + static_cast<int>(r * std::sin(a)));
        }
        if (thick == cv::FILLED)
          cv::fillPoly(img, std::vector<std::vector<cv::Point>>{poly}, col, cv::LINE_AA);
        else
          cv::polylines(img, poly, true, col, thick, cv::LINE_AA);
        break;
      }
      default: {
        const double a = uni(rng, 0, CV_PI);
        const cv::Point d(static_cast<int>(s * std::cos(a)), static_cast<int>(s * std::sin(a)));
        cv::line(img, c - d, c + d, col, uniInt(rng, 1, std::max(1, s / 10)), cv::LINE_AA);
      }
    }
  }
}

const std::vector<std::string> kWords = {
    "ROBOT", "GRASP", "Morning", "CRUNCH", "tea", "Green", "ORGANIC", "2024", "net wt 375g",
    "Vision", "Servo", "Enon", "Kyoto", "LIMITED", "Fresh!", "No. 7", "Jazz Night", "OPEN",
    "Chapter", "MILK", "Oats", "honey", "SALE 50%", "Fuji", "express", "Atlas", "Nova", "BLUE",
    "classic", "Premium", "Recipe", "#42", "since 1887", "Delta", "Orbit", "Festival", "ticket"};

int randomFont(Rng& rng) {
  static const int fonts[] = {cv::FONT_HERSHEY_SIMPLEX, cv::FONT_HERSHEY_DUPLEX,
                              cv::FONT_HERSHEY_COMPLEX, cv::FONT_HERSHEY_TRIPLEX,
                              cv::FONT_HERSHEY_PLAIN,   cv::FONT_HERSHEY_SCRIPT_SIMPLEX,
                              cv::FONT_HERSHEY_COMPLEX_SMALL};
  int f = fonts[uniInt(rng, 0, 6)];
  if (coin(rng, 0.25)) f |= cv::FONT_ITALIC;
  return f;
}

std::string randomWord(Rng& rng) {
  if (coin(rng, 0.2)) return std::to_string(uniInt(rng, 0, 99999));
  return kWords[static_cast<size_t>(uniInt(rng, 0, static_cast<int>(kWords.size()) - 1))];
}

/// Text of height scale*~22 px at a random angle, blended into img through a rotated AA mask.
void drawText(cv::Mat& img, const std::string& text, cv::Point centre, double scale, double angle_deg,
              int font, int gray, int thickness) {
  int base = 0;
  const cv::Size ts = cv::getTextSize(text, font, scale, thickness, &base);
  const int side = static_cast<int>(std::hypot(ts.width, ts.height + base)) + 4;
  cv::Mat mask = cv::Mat::zeros(side, side, CV_8U);
  cv::putText(mask, text, cv::Point((side - ts.width) / 2, (side + ts.height) / 2), font, scale,
              cv::Scalar(255), thickness, cv::LINE_AA);
  const cv::Mat rot = cv::getRotationMatrix2D(cv::Point2f(side / 2.f, side / 2.f), angle_deg, 1.0);
  cv::warpAffine(mask, mask, rot, mask.size(), cv::INTER_LINEAR);
  for (int y = 0; y < side; ++y)
    for (int x = 0; x < side; ++x) {
      const int ix = centre.x - side / 2 + x, iy = centre.y - side / 2 + y;
      if (ix < 0 || iy < 0 || ix >= img.cols || iy >= img.rows) continue;
      const int a = mask.at<uchar>(y, x);
      uchar& p = img.at<uchar>(iy, ix);
      p = static_cast<uchar>((gray * a + p * (255 - a) + 127) / 255);
    }
}

void drawRandomText(cv::Mat& img, int n, double min_scale, double max_scale, double max_angle_deg,
                    Rng& rng) {
  for (int i = 0; i < n; ++i) {
    const cv::Point c(uniInt(rng, 0, img.cols - 1), uniInt(rng, 0, img.rows - 1));
    const double scale = min_scale * std::pow(max_scale / min_scale, uni(rng, 0, 1));
    const int thick = std::max(1, static_cast<int>(scale * uni(rng, 0.8, 2.5)));
    drawText(img, randomWord(rng), c, scale, uni(rng, -max_angle_deg, max_angle_deg), randomFont(rng),
             contrasting(rng, grayAt(img, c), 70), thick);
  }
}

/// Smooth multi-scale base with gradients and blobs: the "paper" of a printed surface.
cv::Mat richBase(int w, int h, Rng& rng, double contrast) {
  cv::Mat f = 0.45 * fractalNoise(w, h, w / 3.0, 6, rng) + 0.55 * linearGradient(w, h, rng);
  cv::normalize(f, f, 0, 1, cv::NORM_MINMAX);
  const double mid = uni(rng, 90, 170);
  return toGray8(f, mid - contrast / 2, mid + contrast / 2);
}

struct TargetStyle {
  int big_shapes, small_shapes, big_text, small_text;
  double max_angle_deg;
};

cv::Mat targetTexture(int w, int h, uint64_t seed, const TargetStyle& st) {
  Rng rng(seed);
  cv::Mat img = richBase(w, h, rng, 120);
  drawShapes(img, st.big_shapes, w / 6, w / 2, rng);
  // Blobs of fine noise give corner-rich patches at the finest scale.
  cv::Mat fine = toGray8(fractalNoise(w, h, 12, 3, rng), 0, 255);
  cv::Mat blob_mask = toGray8(noiseField(w, h, w / 5.0, rng), 0, 255);
  cv::threshold(blob_mask, blob_mask, 175, 255, cv::THRESH_BINARY);
  fine.copyTo(img, blob_mask);
  drawShapes(img, st.small_shapes, 6, w / 10, rng);
  drawRandomText(img, st.big_text, 1.2, 3.0, st.max_angle_deg, rng);
  drawRandomText(img, st.small_text, 0.35, 1.1, st.max_angle_deg, rng);
  cv::rectangle(img, cv::Rect(0, 0, w, h), cv::Scalar(contrasting(rng, grayAt(img, {0, 0}))),
                uniInt(rng, 2, 6));
  return img;
}

/// Columns of small text lines and a few photos: a magazine page.
cv::Mat magazineTexture(int w, int h, uint64_t seed) {
  Rng rng(seed);
  cv::Mat img(h, w, CV_8U, cv::Scalar(uniInt(rng, 200, 235)));
  drawText(img, "ATLAS", {w / 2, 32}, 2.2, 0, cv::FONT_HERSHEY_TRIPLEX, 20, 4);
  for (int p = 0; p < 3; ++p) {
    const cv::Rect r(uniInt(rng, 5, w - 150), uniInt(rng, 60, h - 110), uniInt(rng, 80, 140),
                     uniInt(rng, 60, 100));
    cv::Mat photo = toGray8(fractalNoise(r.width, r.height, r.width / 2.0, 2, rng), 20, 235);
    drawShapes(photo, 6, 8, r.width / 2, rng);
    photo.copyTo(img(r & cv::Rect(0, 0, w, h)));
  }
  for (int y = 70; y < h - 8; y += uniInt(rng, 9, 14))
    for (int col = 0; col < 2; ++col) {
      const int x0 = 8 + col * w / 2;
      if (coin(rng, 0.35)) continue;
      std::string line;
      while (line.size() < static_cast<size_t>(uniInt(rng, 10, 24))) line += randomWord(rng) + " ";
      cv::putText(img, line, {x0, y}, cv::FONT_HERSHEY_PLAIN, uni(rng, 0.55, 0.8), cv::Scalar(uniInt(rng, 0, 70)),
                  1, cv::LINE_AA);
    }
  drawRandomText(img, 4, 0.8, 1.6, 30, rng);
  return img;
}

/// One 50x50 motif tiled 8x8: every feature has many identical twins.
cv::Mat tiledTexture(uint64_t seed) {
  Rng rng(seed);
  cv::Mat motif = richBase(50, 50, rng, 100);
  drawShapes(motif, 5, 6, 25, rng);
  drawText(motif, "R7", {25, 25}, 0.7, 20, cv::FONT_HERSHEY_DUPLEX, 10, 1);
  cv::Mat img;
  cv::repeat(motif, 8, 8, img);
  return img;
}

/// Four-fold rotational and mirror symmetry (the dihedral group of the square).
cv::Mat symmetricTexture(uint64_t seed) {
  Rng rng(seed);
  cv::Mat q = richBase(200, 200, rng, 130);
  drawShapes(q, 25, 8, 80, rng);
  drawRandomText(q, 6, 0.5, 1.5, 60, rng);
  cv::Mat img(400, 400, CV_8U);
  cv::Mat tr, bl, br;
  cv::flip(q, tr, 1);
  cv::flip(q, bl, 0);
  cv::flip(q, br, -1);
  q.copyTo(img(cv::Rect(0, 0, 200, 200)));
  tr.copyTo(img(cv::Rect(200, 0, 200, 200)));
  bl.copyTo(img(cv::Rect(0, 200, 200, 200)));
  br.copyTo(img(cv::Rect(200, 200, 200, 200)));
  // Symmetrise across the diagonal too so rotations by 90 degrees map it onto itself.
  cv::Mat t = img.t();
  cv::addWeighted(img, 0.5, t, 0.5, 0, img);
  return img;
}

/// Mostly smooth shading, a few soft shapes and one small label: few SIFT features.
cv::Mat lowTexture(uint64_t seed) {
  Rng rng(seed);
  cv::Mat f = 0.7 * linearGradient(400, 300, rng) + 0.3 * noiseField(400, 300, 150, rng);
  cv::normalize(f, f, 0, 1, cv::NORM_MINMAX);
  cv::Mat img = toGray8(f, 120, 170);
  cv::circle(img, {120, 150}, 70, cv::Scalar(185), cv::FILLED, cv::LINE_AA);
  cv::GaussianBlur(img, img, cv::Size(0, 0), 6);
  drawText(img, "plain", {300, 240}, 0.9, 0, cv::FONT_HERSHEY_SIMPLEX, 90, 2);
  return img;
}

cv::Mat wallTexture(uint64_t seed) {
  Rng rng(seed);
  cv::Mat f = 0.6 * fractalNoise(640, 480, 300, 40, rng) + 0.4 * linearGradient(640, 480, rng);
  cv::normalize(f, f, 0, 1, cv::NORM_MINMAX);
  cv::Mat img = toGray8(f, 150, 200);
  cv::Mat grain = toGray8(noiseField(640, 480, 1.5, rng), 0, 12);
  img += grain;
  // A door frame, a skirting board, a light switch and a framed picture.
  cv::rectangle(img, cv::Rect(440, 90, 140, 390), cv::Scalar(120), 6, cv::LINE_AA);
  cv::rectangle(img, cv::Rect(0, 455, 640, 25), cv::Scalar(95), cv::FILLED);
  cv::rectangle(img, cv::Rect(400, 250, 18, 28), cv::Scalar(225), cv::FILLED);
  cv::Mat pic = toGray8(fractalNoise(150, 100, 60, 4, rng), 30, 220);
  pic.copyTo(img(cv::Rect(90, 120, 150, 100)));
  cv::rectangle(img, cv::Rect(86, 116, 158, 108), cv::Scalar(40), 4);
  return img;
}

cv::Mat floorTexture(uint64_t seed) {
  Rng rng(seed);
  cv::Mat f = fractalNoise(512, 512, 128, 2, rng);
  cv::Mat img = toGray8(f, 80, 140);
  for (int i = 0; i <= 512; i += 128) {  // tile joints
    cv::line(img, {i, 0}, {i, 511}, cv::Scalar(60), 2);
    cv::line(img, {0, i}, {511, i}, cv::Scalar(60), 2);
  }
  return img;
}

cv::Mat woodTexture(uint64_t seed) {
  Rng rng(seed);
  const int w = 512, h = 256;
  cv::Mat warp = fractalNoise(w, h, 64, 8, rng);
  cv::Mat fine = noiseField(w, h, 2, rng);
  cv::Mat img(h, w, CV_8U);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      // Grain runs along x: rings are level sets of y displaced by low-frequency noise.
      const double r = y * 0.18 + 9.0 * warp.at<float>(y, x) + 0.002 * x;
      const double v = 0.5 + 0.35 * std::sin(r) + 0.15 * std::sin(3.1 * r) + 0.08 * fine.at<float>(y, x);
      img.at<uchar>(y, x) = cv::saturate_cast<uchar>(90 + 90 * v);
    }
  for (int k = 0; k < 3; ++k)  // knots
    cv::ellipse(img, {uniInt(rng, 30, w - 30), uniInt(rng, 20, h - 20)}, {uniInt(rng, 8, 18), uniInt(rng, 4, 8)},
                0, 0, 360, cv::Scalar(70), 2, cv::LINE_AA);
  cv::line(img, {0, h / 2}, {w - 1, h / 2}, cv::Scalar(55), 1, cv::LINE_AA);  // plank joint
  return img;
}

/// Distractor / background patches, each with a different character.
cv::Mat clutterTexture(int kind, uint64_t seed) {
  Rng rng(seed);
  const int n = 256;
  cv::Mat img;
  switch (kind % 8) {
    case 0: {  // stripes
      img = richBase(n, n, rng, 60);
      const double a = uni(rng, 0, CV_PI), per = uni(rng, 8, 24);
      for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x)
          if (std::fmod(std::abs(x * std::cos(a) + y * std::sin(a)), per) < per / 2) img.at<uchar>(y, x) /= 2;
      break;
    }
    case 1:  // dense text
      img = cv::Mat(n, n, CV_8U, cv::Scalar(uniInt(rng, 180, 240)));
      drawRandomText(img, 40, 0.4, 1.4, 90, rng);
      break;
    case 2:  // blobs
      img = toGray8(fractalNoise(n, n, 64, 4, rng), 10, 245);
      break;
    case 3:  // shapes
      img = richBase(n, n, rng, 80);
      drawShapes(img, 60, 6, 70, rng);
      break;
    case 4: {  // irregular checker
      img = cv::Mat(n, n, CV_8U);
      const int cell = uniInt(rng, 12, 30);
      for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) img.at<uchar>(y, x) = ((x / cell + y / cell) % 2) ? 200 : 60;
      drawShapes(img, 15, 10, 60, rng);
      break;
    }
    case 5:  // fine noise cloth
      img = toGray8(fractalNoise(n, n, 16, 1.5, rng), 40, 220);
      break;
    case 6:  // mixed poster
      img = targetTexture(n, n, seed, {6, 40, 2, 10, 90});
      break;
    default:  // labels and barcodes
      img = cv::Mat(n, n, CV_8U, cv::Scalar(230));
      for (int x = 20; x < n - 20;) {
        const int bw = uniInt(rng, 1, 4);
        cv::rectangle(img, cv::Rect(x, 30, bw, 80), cv::Scalar(10), cv::FILLED);
        x += bw + uniInt(rng, 1, 4);
      }
      drawRandomText(img, 12, 0.5, 1.2, 10, rng);
      drawShapes(img, 10, 10, 50, rng);
  }
  return img;
}

/// Printed cardboard box faces: kraft base, printed panel, handling symbols.
cv::Mat boxFace(int w, int h, uint64_t seed, const std::string& label) {
  Rng rng(seed);
  cv::Mat img = toGray8(fractalNoise(w, h, 80, 2, rng), 135, 175);
  cv::Mat panel = targetTexture(w / 2, h / 2, seed + 1, {4, 25, 1, 8, 20});
  panel.copyTo(img(cv::Rect(w / 4, h / 4, w / 2, h / 2)));
  drawText(img, label, {w / 2, h / 8}, 1.3, 0, cv::FONT_HERSHEY_DUPLEX, 35, 2);
  drawText(img, "THIS SIDE UP", {w / 2, h - h / 10}, 0.6, 0, cv::FONT_HERSHEY_SIMPLEX, 40, 1);
  cv::arrowedLine(img, {w / 10, h - 20}, {w / 10, h - 60}, cv::Scalar(40), 3, cv::LINE_AA, 0, 0.3);
  cv::rectangle(img, cv::Rect(0, 0, w, h), cv::Scalar(100), 3);
  return img;
}

int makeMedia(int argc, char** argv) {
  CLI::App app{"Generate the project's grayscale textures (deterministic, fixed seeds).\n"
               "Exit status: 0 written; 2 bad options; 3 a texture could not be written."};
  std::string out = "media";
  app.add_option("--out", out, "output directory (media/ of the source tree)");
  tool::parse(app, argc, argv);

  namespace fs = std::filesystem;
  struct Item {
    std::string path;
    std::function<cv::Mat()> make;
  };
  const std::vector<Item> items = {
      {"targets/poster_concert.png", [] { return targetTexture(400, 300, 1001, {8, 60, 5, 30, 45}); }},
      {"targets/cereal_box.png", [] { return targetTexture(400, 400, 1002, {14, 50, 4, 25, 20}); }},
      {"targets/book_cover.png", [] { return targetTexture(400, 300, 1003, {5, 80, 3, 40, 90}); }},
      {"targets/tea_box.png", [] { return targetTexture(400, 400, 1004, {10, 90, 6, 20, 10}); }},
      {"targets/magazine.png", [] { return magazineTexture(400, 300, 1005); }},
      {"hard/tiled_motif.png", [] { return tiledTexture(2001); }},
      {"hard/symmetric.png", [] { return symmetricTexture(2002); }},
      {"hard/low_texture.png", [] { return lowTexture(2003); }},
      {"backgrounds/wall.png", [] { return wallTexture(3001); }},
      {"backgrounds/floor.png", [] { return floorTexture(3002); }},
      {"backgrounds/table_wood.png", [] { return woodTexture(3003); }},
      {"boxes/box_side_a.png", [] { return boxFace(400, 300, 4001, "FRAGILE"); }},
      {"boxes/box_side_b.png", [] { return boxFace(400, 300, 4002, "KEEP DRY"); }},
      {"boxes/box_top.png", [] { return boxFace(400, 400, 4003, "PARCEL"); }},
  };
  std::vector<Item> all = items;
  for (int k = 0; k < 8; ++k) {
    char name[64];
    std::snprintf(name, sizeof name, "clutter/clutter_%02d.png", k);
    all.push_back({name, [k] { return clutterTexture(k, 5000 + static_cast<uint64_t>(k)); }});
  }

  uintmax_t total = 0;
  for (const Item& it : all) {
    const fs::path p = fs::path(out) / it.path;
    tool::makeOutputDir(p.parent_path().string());
    const cv::Mat img = it.make();
    CV_Assert(img.type() == CV_8UC1);
    tool::writeImage(p.string(), img, {cv::IMWRITE_PNG_COMPRESSION, 9});
    total += fs::file_size(p);
    std::cout << "wrote " << p.string() << " (" << img.cols << "x" << img.rows << ", "
              << fs::file_size(p) / 1024 << " KiB)\n";
  }
  std::cout << all.size() << " textures, " << total / 1024 << " KiB in total\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return refgrasp::tool::run("make_media", argc, argv, makeMedia); }
