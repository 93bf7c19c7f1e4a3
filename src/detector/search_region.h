#pragma once
// Where one object is searched in a frame: the whole image, a query's region, or the region and
// keypoint sizes a predicted pose gives (ObjectPrior). Internal to the detector library.
#include <opencv2/core.hpp>

#include "detector/registered_object.h"

namespace refgrasp::detector {

/// What one object searches in a frame.
struct Search {
  bool searched = true;  ///< false: only_priors and no prior
  cv::Rect roi;          ///< image px, clipped to the image; empty: none of the region is in it
  ExtractRegion region;  ///< what the extraction is asked for (roi empty = whole image)
  /// Both ask for the same features (one extraction serves both).
  bool sameExtraction(const Search& o) const {
    return region.roi == o.region.roi && region.min_size_px == o.region.min_size_px &&
           region.max_size_px == o.region.max_size_px && region.inner_margin_px == o.region.inner_margin_px &&
           region.downsample == o.region.downsample;
  }
};

/// The search for one object in a frame of `camera` (prior: its entry in the query, or null).
Search searchFor(const RegisteredObject& obj, const ObjectPrior* prior, const DetectionQuery& q,
                 const Intrinsics& camera);

}  // namespace refgrasp::detector
