#include "eval/classic.h"

#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

namespace refgrasp::eval {

ClassicFeatures classicSift(const cv::Mat& gray) {
  static const cv::Ptr<cv::SIFT> sift = cv::SIFT::create();
  ClassicFeatures f;
  sift->detectAndCompute(gray, cv::noArray(), f.keypoints, f.descriptors);
  return f;
}

ClassicPipeline::ClassicPipeline(const detector::ObjectModel& object, ClassicOptions opt)
    : object_(object), opt_(opt) {
  const ClassicFeatures all = classicSift(object.reference);
  std::vector<cv::Point2f> poly;
  for (const auto& p : object.pattern_polygon_px) poly.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
  for (size_t i = 0; i < all.keypoints.size(); ++i) {
    if (!poly.empty() && cv::pointPolygonTest(poly, all.keypoints[i].pt, false) < 0) continue;
    ref_keypoints_.push_back(all.keypoints[i]);
    ref_descriptors_.push_back(all.descriptors.row(static_cast<int>(i)));
  }
}

ClassicResult ClassicPipeline::detect(const ClassicFeatures& scene, const Intrinsics& camera) const {
  ClassicResult r;
  if (ref_keypoints_.size() < 4 || scene.keypoints.size() < 4) return r;
  cv::BFMatcher bf(cv::NORM_L2);
  std::vector<std::vector<cv::DMatch>> knn;
  bf.knnMatch(ref_descriptors_, scene.descriptors, knn, 2);
  std::vector<cv::Point2f> a, b;
  std::vector<int> ref_index;
  for (const auto& m : knn)
    if (m.size() == 2 && m[0].distance < opt_.ratio * m[1].distance) {
      a.push_back(ref_keypoints_[m[0].queryIdx].pt);
      b.push_back(scene.keypoints[m[0].trainIdx].pt);
      ref_index.push_back(m[0].queryIdx);
    }
  if (a.size() < 4) return r;
  std::vector<uchar> mask;
  const cv::Mat H = cv::findHomography(a, b, cv::RANSAC, opt_.ransac_reproj_px, mask);
  if (H.empty()) return r;
  int inliers = 0;
  for (uchar m : mask) inliers += m != 0;
  if (inliers < opt_.min_inliers) return r;
  r.found = true;
  r.inliers = inliers;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r.H(i, j) = H.at<double>(i, j);
  if (!object_.target) return r;
  // IPPE + LM on the inliers: reference px back-projected onto the pattern plane (object frame).
  const Pose pMo = object_.target->oMp.inverse();
  std::vector<cv::Point3d> X;
  std::vector<cv::Point2d> y;
  for (size_t k = 0; k < mask.size(); ++k) {
    if (!mask[k]) continue;
    Eigen::Vector2d pr(a[k].x, a[k].y);
    if (object_.camera) pr = object_.camera->undistortPixel(pr);
    const auto Xo = object_.target->backProject(pr);
    if (!Xo) continue;
    const Eigen::Vector3d Xp = pMo * *Xo;
    X.emplace_back(Xp.x(), Xp.y(), 0.0);
    y.emplace_back(b[k].x, b[k].y);
  }
  if (X.size() < 4) return r;
  cv::Mat K(3, 3, CV_64F), dist(1, 5, CV_64F);
  const Eigen::Matrix3d Ke = camera.K();
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) K.at<double>(i, j) = Ke(i, j);
  for (int i = 0; i < 5; ++i) dist.at<double>(i) = camera.dist[i];
  cv::Mat rvec, tvec;
  try {
    if (!cv::solvePnP(X, y, K, dist, rvec, tvec, false, cv::SOLVEPNP_IPPE)) return r;
    cv::solvePnPRefineLM(X, y, K, dist, rvec, tvec);
  } catch (const cv::Exception&) {
    return r;
  }
  const Pose cMp = Pose::fromRotationVector({rvec.at<double>(0), rvec.at<double>(1), rvec.at<double>(2)},
                                            {tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2)});
  r.cMo = cMp * pMo;
  return r;
}

}  // namespace refgrasp::eval
