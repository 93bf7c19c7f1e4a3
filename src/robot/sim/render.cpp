#include "robot/sim/render.h"

#include <algorithm>
#include <cmath>
#include <deque>
#include <memory>
#include <mutex>
#include <numeric>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "core/cylinder.h"
#include "core/geometry.h"
#include "core/error.h"

namespace refgrasp::sim {

void RenderOptions::check() const {
  refgrasp::check(std::isfinite(near_m) && near_m > 0, "RenderOptions.near_m", "must be positive");
  refgrasp::check(background_gray >= 0 && background_gray <= 255, "RenderOptions.background_gray",
                  "must be in [0, 255]");
}

namespace {

using Poly2 = std::vector<Eigen::Vector2d>;

std::array<Eigen::Vector3d, 4> planeCorners(const TexturedPlane& p) {
  const double w = p.width_m / 2, h = p.height_m / 2;
  return {Eigen::Vector3d(-w, -h, 0), Eigen::Vector3d(w, -h, 0), Eigen::Vector3d(w, h, 0),
          Eigen::Vector3d(-w, h, 0)};
}

void checkPlane(const TexturedPlane& p) {
  refgrasp::check(!p.texture.empty() && p.texture.type() == CV_8UC1, "TexturedPlane.texture",
                  "must be a non-empty CV_8UC1 image");
  refgrasp::check(std::isfinite(p.width_m) && std::isfinite(p.height_m) && p.width_m > 0 &&
                      p.height_m > 0,
                  "TexturedPlane", "width_m and height_m must be positive");
  refgrasp::check(p.cMp.isFinite(), "TexturedPlane.cMp", "must be finite");
}

Eigen::Matrix3d textureToImageK(const Eigen::Matrix3d& K, const TexturedPlane& p) {
  const double W = p.texture.cols, H = p.texture.rows;
  const double sx = p.width_m / W, sy = p.height_m / H;
  Eigen::Matrix3d A;  // texture pixel -> plane (x, y, 1)
  A << sx, 0, -(W - 1) / 2 * sx, 0, sy, -(H - 1) / 2 * sy, 0, 0, 1;
  Eigen::Matrix3d Rt;
  Rt << p.cMp.R.col(0), p.cMp.R.col(1), p.cMp.t;
  return K * Rt * A;
}

// Sutherland-Hodgman: keeps the part of a convex polygon where signedDist >= 0.
template <class V, class F>
std::vector<V> clip(const std::vector<V>& in, F signedDist) {
  std::vector<V> out;
  for (size_t i = 0; i < in.size(); ++i) {
    const V& a = in[i];
    const V& b = in[(i + 1) % in.size()];
    const double da = signedDist(a), db = signedDist(b);
    if (da >= 0) out.push_back(a);
    if ((da >= 0) != (db >= 0)) out.push_back(a + (b - a) * (da / (da - db)));
  }
  return out;
}

// Gaussian pyramids of textures, keyed by the pixel buffer. The entry holds a reference to the
// texture, so a buffer cannot be freed and reused by another image while it is cached.
class PyramidCache {
 public:
  std::vector<cv::Mat> get(const cv::Mat& tex, int levels) {
    std::lock_guard<std::mutex> lock(mu_);
    for (auto& e : entries_)
      if (e.tex.data == tex.data && e.tex.size() == tex.size() && e.tex.step == tex.step) {
        while (static_cast<int>(e.levels.size()) <= levels) {
          cv::Mat down;
          cv::pyrDown(e.levels.back(), down);
          e.levels.push_back(down);
        }
        return e.levels;
      }
    if (entries_.size() >= kMaxEntries) entries_.pop_front();
    Entry e{tex, {tex}};
    while (static_cast<int>(e.levels.size()) <= levels) {
      cv::Mat down;
      cv::pyrDown(e.levels.back(), down);
      e.levels.push_back(down);
    }
    entries_.push_back(e);
    return e.levels;
  }

 private:
  struct Entry {
    cv::Mat tex;
    std::vector<cv::Mat> levels;
  };
  static constexpr size_t kMaxEntries = 128;
  std::mutex mu_;
  std::deque<Entry> entries_;
};

PyramidCache& pyramidCache() {
  static PyramidCache cache;
  return cache;
}

// Ideal canvas covering every sample a distorted image needs, and the remap into the output.
struct DistortionMap {
  Intrinsics cam;
  int ox = 0, oy = 0;  // canvas pixel = ideal pixel - (ox, oy)
  cv::Size canvas;
  cv::Mat map1, map2;  // fixed-point maps for cv::remap
};

bool sameIntrinsics(const Intrinsics& a, const Intrinsics& b) {
  return a.width == b.width && a.height == b.height && a.fx == b.fx && a.fy == b.fy &&
         a.cx == b.cx && a.cy == b.cy && a.dist == b.dist;
}

std::shared_ptr<const DistortionMap> distortionMap(const Intrinsics& cam) {
  static std::mutex mu;
  static std::deque<std::shared_ptr<const DistortionMap>> cache;
  {
    std::lock_guard<std::mutex> lock(mu);
    for (const auto& m : cache)
      if (sameIntrinsics(m->cam, cam)) return m;
  }
  auto m = std::make_shared<DistortionMap>();
  m->cam = cam;
  cv::Mat xy(cam.height, cam.width, CV_32FC2);
  double minx = 0, miny = 0, maxx = cam.width - 1, maxy = cam.height - 1;
  for (int v = 0; v < cam.height; ++v)
    for (int u = 0; u < cam.width; ++u) {
      const Eigen::Vector2d p = cam.undistortPixel(Eigen::Vector2d(u, v));
      xy.at<cv::Vec2f>(v, u) = cv::Vec2f(static_cast<float>(p.x()), static_cast<float>(p.y()));
      minx = std::min(minx, p.x());
      maxx = std::max(maxx, p.x());
      miny = std::min(miny, p.y());
      maxy = std::max(maxy, p.y());
    }
  // Strong distortion can ask for huge canvases; beyond 3x the image size samples replicate.
  minx = std::max(minx, -1.0 * cam.width);
  miny = std::max(miny, -1.0 * cam.height);
  maxx = std::min(maxx, 2.0 * cam.width);
  maxy = std::min(maxy, 2.0 * cam.height);
  m->ox = static_cast<int>(std::floor(minx)) - 2;
  m->oy = static_cast<int>(std::floor(miny)) - 2;
  m->canvas = cv::Size(static_cast<int>(std::ceil(maxx)) + 3 - m->ox,
                       static_cast<int>(std::ceil(maxy)) + 3 - m->oy);
  xy -= cv::Scalar(m->ox, m->oy);
  cv::convertMaps(xy, cv::noArray(), m->map1, m->map2, CV_16SC2);
  std::lock_guard<std::mutex> lock(mu);
  if (cache.size() >= 8) cache.pop_front();
  cache.push_back(m);
  return m;
}

// Edges of a convex polygon as signed distances nx*x + ny*y + c (> 0 inside), in ROI coordinates.
struct Edge {
  double nx, ny, c;
};

std::vector<Edge> polygonEdges(const Poly2& poly, const cv::Rect& roi) {
  const double orient = shoelace2(poly.data(), poly.size()) >= 0 ? 1.0 : -1.0;
  std::vector<Edge> edges;
  for (size_t i = 0; i < poly.size(); ++i) {
    const Eigen::Vector2d a = poly[i] - Eigen::Vector2d(roi.x, roi.y);
    const Eigen::Vector2d d = poly[(i + 1) % poly.size()] - poly[i];
    const double len = d.norm();
    if (len < 1e-12) continue;
    const double nx = -orient * d.y() / len, ny = orient * d.x() / len;
    edges.push_back({nx, ny, -(nx * a.x() + ny * a.y())});
  }
  return edges;
}

// Columns [lo, hi] of row y where every edge distance is >= k (lo > hi: none).
void rowSpan(const std::vector<Edge>& edges, double y, double k, int width, int* lo, int* hi) {
  double l = 0, h = width - 1;
  for (const Edge& e : edges) {
    const double cy = e.ny * y + e.c;
    if (e.nx > 1e-12)
      l = std::max(l, (k - cy) / e.nx);
    else if (e.nx < -1e-12)
      h = std::min(h, (k - cy) / e.nx);
    else if (cy < k)
      h = -1;
  }
  *lo = static_cast<int>(std::ceil(std::max(l, -1.0)));
  *hi = static_cast<int>(std::floor(std::min(h, static_cast<double>(width))));
}

// inv_depth: per-pixel 1/z of the nearest plane drawn so far (0 = nothing): a depth test.
void drawPlane(cv::Mat& canvas, cv::Mat& inv_depth, const Eigen::Matrix3d& K, const TexturedPlane& p,
               const RenderOptions& opt) {
  const Pose& cMp = p.cMp;
  // Visible side: the camera centre lies on the plane's -z side, i.e. n . t > 0.
  if (cMp.R.col(2).dot(cMp.t) <= 0) return;

  std::vector<Eigen::Vector3d> poly3;
  for (const auto& c : planeCorners(p)) poly3.push_back(cMp * c);
  poly3 = clip(poly3, [&](const Eigen::Vector3d& X) { return X.z() - opt.near_m; });
  if (poly3.size() < 3) return;

  Poly2 poly;
  for (const auto& X : poly3) poly.push_back((K * X).hnormalized());
  // Guard band: keeps drawing coordinates small when a plane reaches far outside the view.
  const double gx0 = -2, gy0 = -2, gx1 = canvas.cols + 1, gy1 = canvas.rows + 1;
  poly = clip(poly, [&](const Eigen::Vector2d& q) { return q.x() - gx0; });
  poly = clip(poly, [&](const Eigen::Vector2d& q) { return gx1 - q.x(); });
  poly = clip(poly, [&](const Eigen::Vector2d& q) { return q.y() - gy0; });
  poly = clip(poly, [&](const Eigen::Vector2d& q) { return gy1 - q.y(); });
  if (poly.size() < 3) return;

  double minx = 1e30, miny = 1e30, maxx = -1e30, maxy = -1e30;
  for (const auto& q : poly) {
    minx = std::min(minx, q.x());
    maxx = std::max(maxx, q.x());
    miny = std::min(miny, q.y());
    maxy = std::max(maxy, q.y());
  }
  const cv::Rect roi = cv::Rect(cv::Point(static_cast<int>(std::floor(minx)) - 1,
                                          static_cast<int>(std::floor(miny)) - 1),
                                cv::Point(static_cast<int>(std::ceil(maxx)) + 2,
                                          static_cast<int>(std::ceil(maxy)) + 2)) &
                       cv::Rect(0, 0, canvas.cols, canvas.rows);
  if (roi.empty()) return;

  // Canvas pixel -> level-0 texture pixel, x_tex ~ M x_img.
  const Eigen::Matrix3d M = textureToImageK(K, p).inverse();
  // Texture pixels per image pixel: sqrt |det J| of the map, det J = det M / w^3. The pyramid
  // level (cv::pyrDown, level-L pixel i centred on level-0 pixel 2^L i) is chosen per row.
  const double detM = std::abs(M.determinant());
  const int max_level =
      opt.mipmap ? std::max(0, static_cast<int>(std::floor(std::log2(std::min(p.texture.cols, p.texture.rows) / 8.0))))
                 : 0;
  const auto levelAt = [&](double w) {
    const double minification = std::sqrt(detM / std::abs(w * w * w));
    if (!(minification >= 2)) return 0;
    return std::min(max_level, static_cast<int>(std::floor(std::log2(minification))));
  };
  int needed = 0;  // deepest level any corner needs
  for (const auto& q : poly) needed = std::max(needed, levelAt(M.row(2).dot(q.homogeneous())));
  const std::vector<cv::Mat> pyramid =
      needed == 0 ? std::vector<cv::Mat>{p.texture} : pyramidCache().get(p.texture, needed);
  cv::Mat tex;
  double scale = 1;  // level-0 -> level-L texture coordinates
  int tw = 0, th = 0;
  // Homogeneous texture coordinates (a, b, w) are linear along a row; sample at a / w, b / w.
  const auto sample = [&](double a, double b, double w) {
    // Clamping replicates the border texels (the coverage mask cuts the plane's outline).
    const double inv = 1.0 / w;
    const double u = std::clamp(a * inv * scale, 0.0, tw - 1.0);
    const double v = std::clamp(b * inv * scale, 0.0, th - 1.0);
    const int iu = static_cast<int>(u), iv = static_cast<int>(v);
    const int iu1 = std::min(iu + 1, tw - 1), iv1 = std::min(iv + 1, th - 1);
    const float fu = static_cast<float>(u - iu), fv = static_cast<float>(v - iv);
    const uchar* r0 = tex.ptr<uchar>(iv);
    const uchar* r1 = tex.ptr<uchar>(iv1);
    const float top = r0[iu] + fu * (r0[iu1] - r0[iu]);
    const float bottom = r1[iu] + fu * (r1[iu1] - r1[iu]);
    return static_cast<int>(top + fv * (bottom - top) + 0.5f);
  };

  // Coverage: with anti-aliasing, the product over edges of clamp(0.5 + signed distance of the
  // pixel centre): exact area for a single axis-aligned edge, unbiased for oblique ones; without,
  // a pixel is in when its centre is. Inside the row span where every distance is >= 0.5 (or 0)
  // coverage is 1.
  const std::vector<Edge> edges = polygonEdges(poly, roi);
  const double k_any = opt.antialias_edges ? -0.5 : 0.0, k_full = opt.antialias_edges ? 0.5 : 0.0;
  // On the plane n.X = n.t, the ray X = z K^-1 (u, v, 1) has 1/z = n^T K^-1 (u, v, 1) / n.t,
  // linear in the pixel coordinates.
  const Eigen::Vector3d g = (K.inverse().transpose() * cMp.R.col(2)) / cMp.R.col(2).dot(cMp.t);
  cv::Mat dst = canvas(roi), zbuf = inv_depth(roi);
  for (int y = 0; y < roi.height; ++y) {
    int x0, x1, f0, f1;
    rowSpan(edges, y, k_any, roi.width, &x0, &x1);
    rowSpan(edges, y, k_full, roi.width, &f0, &f1);
    x0 = std::max(x0, 0);
    x1 = std::min(x1, roi.width - 1);
    uchar* d = dst.ptr<uchar>(y);
    float* zb = zbuf.ptr<float>(y);
    const double Y = y + roi.y, X0 = x0 + roi.x;
    double iz = g.x() * X0 + g.y() * Y + g.z();
    double a = M(0, 0) * X0 + M(0, 1) * Y + M(0, 2);
    double b = M(1, 0) * X0 + M(1, 1) * Y + M(1, 2);
    double w = M(2, 0) * X0 + M(2, 1) * Y + M(2, 2);
    const int level = std::min(needed, levelAt(w + M(2, 0) * 0.5 * (x1 - x0)));
    tex = pyramid[static_cast<size_t>(level)];
    tw = tex.cols;
    th = tex.rows;
    scale = std::ldexp(1.0, -level);
    for (int x = x0; x <= x1; ++x, iz += g.x(), a += M(0, 0), b += M(1, 0), w += M(2, 0)) {
      if (iz < zb[x]) continue;  // behind what is already there
      const int val = sample(a, b, w);
      if (x >= f0 && x <= f1) {
        d[x] = static_cast<uchar>(val);
        zb[x] = static_cast<float>(iz);
        continue;
      }
      double cov = 1;
      for (const Edge& e : edges) {
        const double dist = e.nx * x + e.ny * y + e.c;
        if (dist < k_full) cov *= opt.antialias_edges ? std::max(0.0, 0.5 + dist) : 0.0;
      }
      const int alpha = static_cast<int>(cov * 255 + 0.5);
      if (alpha == 0) continue;
      d[x] = static_cast<uchar>((val * alpha + d[x] * (255 - alpha) + 127) / 255);
      if (alpha >= 128) zb[x] = static_cast<float>(iz);
    }
  }
}

void checkCylinder(const TexturedCylinder& c) {
  refgrasp::check(!c.label.empty() && c.label.type() == CV_8UC1, "TexturedCylinder.label",
                  "must be a non-empty CV_8UC1 image");
  for (const cv::Mat* t : {&c.side_texture, &c.cap_texture})
    refgrasp::check(t->empty() || t->type() == CV_8UC1, "TexturedCylinder", "textures must be CV_8UC1");
  refgrasp::check(std::isfinite(c.radius_m) && c.radius_m > 0 && std::isfinite(c.height_m) && c.height_m > 0 &&
                      std::isfinite(c.label_width_m) && c.label_width_m > 0 && std::isfinite(c.label_height_m) &&
                      c.label_height_m > 0 && c.label_width_m <= 2 * M_PI * c.radius_m * 1.01,
                  "TexturedCylinder", "radius, height and label size must be positive, the label at most 2 pi r wide");
  refgrasp::check(c.cMo.isFinite(), "TexturedCylinder.cMo", "must be finite");
}

// Bilinear sample of a level-L pyramid image at level-0 coordinates (u, v), border replicated.
float samplePyramid(const std::vector<cv::Mat>& pyr, int level, double u, double v) {
  const cv::Mat& t = pyr[static_cast<size_t>(level)];
  // Level `level`'s pixel centres: level-0 pixel u lies at (u + 0.5) / 2^level - 0.5 (cv::pyrDown).
  const double s = std::ldexp(1.0, -level);
  const double x = std::clamp((u + 0.5) * s - 0.5, 0.0, t.cols - 1.0), y = std::clamp((v + 0.5) * s - 0.5, 0.0, t.rows - 1.0);
  const int ix = static_cast<int>(x), iy = static_cast<int>(y);
  const int ix1 = std::min(ix + 1, t.cols - 1), iy1 = std::min(iy + 1, t.rows - 1);
  const float fx = static_cast<float>(x - ix), fy = static_cast<float>(y - iy);
  const uchar* r0 = t.ptr<uchar>(iy);
  const uchar* r1 = t.ptr<uchar>(iy1);
  const float top = r0[ix] + fx * (r0[ix1] - r0[ix]);
  const float bottom = r1[ix] + fx * (r1[ix1] - r1[ix]);
  return top + fy * (bottom - top);
}

// A pyramid level for `minification` texels per pixel (as drawPlane chooses it).
int levelFor(double minification, int max_level) {
  if (!(minification >= 2)) return 0;
  return std::min(max_level, static_cast<int>(std::floor(std::log2(minification))));
}

int maxLevelOf(const cv::Mat& tex, bool mipmap) {
  return mipmap ? std::max(0, static_cast<int>(std::floor(std::log2(std::min(tex.cols, tex.rows) / 8.0)))) : 0;
}

// Ray casting of one cylinder: per pixel the nearest hit of the side or a cap, shaded from the
// label, the side texture or the cap texture. Pixels on the silhouette (their hit status differs
// from a neighbour's) are supersampled 4 x 4 and blended over what is there.
class CylinderDrawer {
 public:
  CylinderDrawer(const TexturedCylinder& c, const Eigen::Matrix3d& K, const RenderOptions& opt)
      : c_(c), opt_(opt), K_(K), Kinv_(K.inverse()), oMc_(c.cMo.inverse()), label_(c.geometry()) {
    f_ = std::sqrt(K(0, 0) * K(1, 1));
  }

  void draw(cv::Mat& canvas, cv::Mat& inv_depth) {
    const cv::Rect roi = bounds(canvas.size());
    if (roi.empty()) return;
    prepareTextures();
    cv::Mat hit(roi.size(), CV_8U, cv::Scalar(0));
    cv::Mat value(roi.size(), CV_32F, cv::Scalar(0));
    cv::Mat iz(roi.size(), CV_32F, cv::Scalar(0));
    for (int y = 0; y < roi.height; ++y)
      for (int x = 0; x < roi.width; ++x) {
        Sample s;
        if (!shade(x + roi.x, y + roi.y, &s)) continue;
        hit.at<uchar>(y, x) = 1;
        value.at<float>(y, x) = s.value;
        iz.at<float>(y, x) = s.inv_depth;
      }
    for (int y = 0; y < roi.height; ++y) {
      uchar* d = canvas.ptr<uchar>(y + roi.y) + roi.x;
      float* zb = inv_depth.ptr<float>(y + roi.y) + roi.x;
      for (int x = 0; x < roi.width; ++x) {
        const bool in = hit.at<uchar>(y, x) != 0;
        bool edge = false;
        if (opt_.antialias_edges)
          for (int dy = -1; dy <= 1 && !edge; ++dy)
            for (int dx = -1; dx <= 1 && !edge; ++dx) {
              const int yy = y + dy, xx = x + dx;
              const bool n = yy >= 0 && xx >= 0 && yy < roi.height && xx < roi.width && hit.at<uchar>(yy, xx) != 0;
              edge = n != in;
            }
        if (!edge) {
          if (in && iz.at<float>(y, x) >= zb[x]) {
            d[x] = static_cast<uchar>(std::clamp(value.at<float>(y, x) + 0.5f, 0.0f, 255.0f));
            zb[x] = iz.at<float>(y, x);
          }
          continue;
        }
        // Silhouette pixel: 4 x 4 samples; coverage blends over what is drawn unless that is nearer.
        double sum = 0, nearest = 0;
        int n = 0;
        for (int sy = 0; sy < 4; ++sy)
          for (int sx = 0; sx < 4; ++sx) {
            Sample s;
            if (!shade(x + roi.x - 0.375 + 0.25 * sx, y + roi.y - 0.375 + 0.25 * sy, &s)) continue;
            sum += s.value;
            nearest = std::max(nearest, static_cast<double>(s.inv_depth));
            ++n;
          }
        if (n == 0 || nearest < zb[x]) continue;
        const double alpha = n / 16.0;
        d[x] = static_cast<uchar>(std::clamp(alpha * sum / n + (1 - alpha) * d[x] + 0.5, 0.0, 255.0));
        if (alpha >= 0.5) zb[x] = static_cast<float>(nearest);
      }
    }
  }

 private:
  struct Sample {
    float value = 0;
    float inv_depth = 0;
  };

  // Image rectangle holding the cylinder's projection: its bounding box's corners projected, the
  // whole canvas when a corner is behind the near plane.
  cv::Rect bounds(cv::Size size) const {
    const double r = c_.radius_m, h = c_.height_m / 2;
    double minx = 1e30, miny = 1e30, maxx = -1e30, maxy = -1e30;
    for (int i = 0; i < 8; ++i) {
      const Eigen::Vector3d Xo((i & 1) ? r : -r, (i & 2) ? h : -h, (i & 4) ? 2 * r : 0);
      const Eigen::Vector3d Xc = c_.cMo * Xo;
      if (Xc.z() < opt_.near_m) return cv::Rect(cv::Point(0, 0), size);
      const Eigen::Vector3d q = K_ * Xc;
      minx = std::min(minx, q.x() / q.z());
      maxx = std::max(maxx, q.x() / q.z());
      miny = std::min(miny, q.y() / q.z());
      maxy = std::max(maxy, q.y() / q.z());
    }
    const cv::Rect box(cv::Point(static_cast<int>(std::floor(std::max(minx, -1.0))) - 1,
                                 static_cast<int>(std::floor(std::max(miny, -1.0))) - 1),
                       cv::Point(static_cast<int>(std::ceil(std::min(maxx, size.width + 1.0))) + 2,
                                 static_cast<int>(std::ceil(std::min(maxy, size.height + 1.0))) + 2));
    return box & cv::Rect(cv::Point(0, 0), size);
  }

  void prepareTextures() {
    label_pyr_ = pyramidCache().get(c_.label, maxLevelOf(c_.label, opt_.mipmap));
    if (!c_.side_texture.empty()) side_pyr_ = pyramidCache().get(c_.side_texture, maxLevelOf(c_.side_texture, opt_.mipmap));
    if (!c_.cap_texture.empty()) cap_pyr_ = pyramidCache().get(c_.cap_texture, maxLevelOf(c_.cap_texture, opt_.mipmap));
  }

  // Shades the canvas point (x, y); false when the ray misses the cylinder.
  bool shade(double x, double y, Sample* out) const {
    const Eigen::Vector3d d = oMc_.R * (Kinv_ * Eigen::Vector3d(x, y, 1));  // object frame, camera z = 1
    const Eigen::Vector3d& o = oMc_.t;
    const double r = c_.radius_m, h = c_.height_m / 2;
    double best = 1e30;
    int what = 0;  // 1 side, 2 cap
    if (const auto t = label_.intersect(o, d)) {
      const double yy = o.y() + *t * d.y();
      if (std::abs(yy) <= h) {
        best = *t;
        what = 1;
      }
    }
    // The cap facing the camera: y = -h seen from y < -h, y = +h from y > h.
    if (std::abs(o.y()) > h && std::abs(d.y()) > 1e-12) {
      const double yc = o.y() < 0 ? -h : h;
      const double t = (yc - o.y()) / d.y();
      if (t > 0 && t < best) {
        const Eigen::Vector3d X = o + t * d;
        if (X.x() * X.x() + (X.z() - r) * (X.z() - r) <= r * r) {
          best = t;
          what = 2;
        }
      }
    }
    if (what == 0) return false;
    // Camera z of the hit is best (the ray's camera-frame direction has z = 1).
    if (best < opt_.near_m) return false;
    const Eigen::Vector3d X = o + best * d;
    const double dist = best * d.norm();
    const Eigen::Vector3d n = what == 1 ? Eigen::Vector3d(X.x(), 0, X.z() - r).normalized()
                                        : Eigen::Vector3d(0, X.y() < 0 ? -1 : 1, 0);
    const double cos_inc = std::max(0.05, std::abs(n.dot(d.normalized())));
    // Surface area one pixel covers (m^2): (dist / f)^2 / cos(incidence).
    const double pixel_m = dist / f_ / std::sqrt(cos_inc);
    out->inv_depth = static_cast<float>(1.0 / best);
    if (what == 2) {
      if (cap_pyr_.empty()) {
        out->value = static_cast<float>(c_.cap_gray);
        return true;
      }
      const cv::Mat& t = c_.cap_texture;
      const double u = (X.x() / (2 * r) + 0.5) * t.cols - 0.5, v = ((X.z() - r) / (2 * r) + 0.5) * t.rows - 0.5;
      const double texel = 2 * r / std::min(t.cols, t.rows);
      out->value = samplePyramid(cap_pyr_, levelFor(pixel_m / texel, static_cast<int>(cap_pyr_.size()) - 1), u, v);
      return true;
    }
    const double ylo = -c_.label_height_m / 2, yhi = c_.label_height_m / 2;
    if (X.y() >= ylo && X.y() <= yhi) {
      if (const auto uv = label_.pixel(X)) {
        const double texel = std::sqrt(label_.metresPerPixelU() * label_.metresPerPixelV());
        out->value = samplePyramid(label_pyr_, levelFor(pixel_m / texel, static_cast<int>(label_pyr_.size()) - 1),
                                   uv->x(), uv->y());
        return true;
      }
    }
    if (side_pyr_.empty()) {
      out->value = static_cast<float>(c_.side_gray);
      return true;
    }
    const cv::Mat& t = c_.side_texture;
    const double theta = std::atan2(X.x(), r - X.z());
    const double u = (theta / (2 * M_PI) + 0.5) * t.cols - 0.5, v = (X.y() / c_.height_m + 0.5) * t.rows - 0.5;
    const double texel = std::sqrt(2 * M_PI * r / t.cols * c_.height_m / t.rows);
    out->value = samplePyramid(side_pyr_, levelFor(pixel_m / texel, static_cast<int>(side_pyr_.size()) - 1), u, v);
    return true;
  }

  const TexturedCylinder& c_;
  const RenderOptions& opt_;
  Eigen::Matrix3d K_, Kinv_;
  Pose oMc_;
  CylinderLabel label_;
  double f_ = 1;
  std::vector<cv::Mat> label_pyr_, side_pyr_, cap_pyr_;
};

}  // namespace

Eigen::Matrix3d textureToImage(const Intrinsics& cam, const TexturedPlane& plane) {
  return textureToImageK(cam.K(), plane);
}

std::array<Eigen::Vector2d, 4> projectPlaneCorners(const Intrinsics& cam, const TexturedPlane& plane) {
  std::array<Eigen::Vector2d, 4> out;
  const auto corners = planeCorners(plane);
  for (size_t i = 0; i < 4; ++i) out[i] = cam.project(plane.cMp * corners[i]);
  return out;
}

cv::Mat renderView(const Intrinsics& cam, const std::vector<TexturedPlane>& planes,
                   const cv::Mat& background, const RenderOptions& opt) {
  return renderView(cam, planes, {}, background, opt);
}

namespace {

// renderView's body; inv_depth (optional) receives the depth buffer of the ideal canvas.
cv::Mat renderCanvas(const Intrinsics& cam, const std::vector<TexturedPlane>& planes,
                     const std::vector<TexturedCylinder>& cylinders, const cv::Mat& background,
                     const RenderOptions& opt, cv::Mat* inv_depth_out) {
  cam.check();
  opt.check();
  for (const auto& p : planes) checkPlane(p);
  for (const auto& c : cylinders) checkCylinder(c);

  std::shared_ptr<const DistortionMap> dmap;
  Eigen::Matrix3d K = cam.K();
  cv::Size canvas_size(cam.width, cam.height);
  if (cam.hasDistortion()) {
    dmap = distortionMap(cam);
    canvas_size = dmap->canvas;
    K(0, 2) -= dmap->ox;
    K(1, 2) -= dmap->oy;
  }

  cv::Mat canvas;
  if (background.empty()) {
    canvas = cv::Mat(canvas_size, CV_8U, cv::Scalar(opt.background_gray));
  } else {
    cv::Mat bg = background;
    if (bg.type() == CV_8UC3)
      cv::cvtColor(background, bg, cv::COLOR_BGR2GRAY);
    else if (bg.type() == CV_8UC4)
      cv::cvtColor(background, bg, cv::COLOR_BGRA2GRAY);
    refgrasp::check(bg.type() == CV_8UC1, "renderView", "background must be an 8-bit image");
    if (bg.size() == canvas_size)
      canvas = bg.clone();
    else
      cv::resize(bg, canvas, canvas_size, 0, 0,
                 bg.cols > canvas_size.width ? cv::INTER_AREA : cv::INTER_LINEAR);
  }

  // Far to near by the distance of each item's centre (planes: the texture centre; cylinders:
  // the axis point at the label's centre row), so anti-aliased edges blend over what is behind.
  struct Item {
    double distance;
    size_t index;
    bool cylinder;
  };
  std::vector<Item> order;
  for (size_t i = 0; i < planes.size(); ++i) order.push_back({planes[i].cMp.t.norm(), i, false});
  for (size_t i = 0; i < cylinders.size(); ++i)
    order.push_back({(cylinders[i].cMo * Eigen::Vector3d(0, 0, cylinders[i].radius_m)).norm(), i, true});
  std::stable_sort(order.begin(), order.end(), [](const Item& a, const Item& b) { return a.distance > b.distance; });
  cv::Mat inv_depth = cv::Mat::zeros(canvas.size(), CV_32F);
  for (const Item& it : order) {
    if (it.cylinder)
      CylinderDrawer(cylinders[it.index], K, opt).draw(canvas, inv_depth);
    else
      drawPlane(canvas, inv_depth, K, planes[it.index], opt);
  }

  if (inv_depth_out) *inv_depth_out = inv_depth;
  if (!dmap) return canvas;
  cv::Mat out;
  cv::remap(canvas, out, dmap->map1, dmap->map2, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  return out;
}

}  // namespace

cv::Mat renderView(const Intrinsics& cam, const std::vector<TexturedPlane>& planes,
                   const std::vector<TexturedCylinder>& cylinders, const cv::Mat& background,
                   const RenderOptions& opt) {
  return renderCanvas(cam, planes, cylinders, background, opt, nullptr);
}

cv::Mat renderViewWithDepth(const Intrinsics& cam, const std::vector<TexturedPlane>& planes,
                            const std::vector<TexturedCylinder>& cylinders, const cv::Mat& background,
                            const RenderOptions& opt, cv::Mat* inv_depth) {
  refgrasp::check(!cam.hasDistortion(), "renderViewWithDepth", "needs a camera without lens distortion");
  return renderCanvas(cam, planes, cylinders, background, opt, inv_depth);
}

}  // namespace refgrasp::sim
