#include "servo/pose_conversions.h"

namespace refgrasp::servo {

vpHomogeneousMatrix toVisp(const Pose& aMb) {
  vpHomogeneousMatrix M;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) M[r][c] = aMb.R(r, c);
    M[r][3] = aMb.t(r);
  }
  return M;
}

Pose fromVisp(const vpHomogeneousMatrix& M) {
  Pose p;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) p.R(r, c) = M[r][c];
    p.t(r) = M[r][3];
  }
  return p;
}

}  // namespace refgrasp::servo
