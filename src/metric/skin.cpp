#include "lodforge/metric/skin.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>

namespace lodforge {
namespace {

// Weights of an influence set with those below `threshold` dropped, as (joint, weight) sorted by joint.
int significant_influences(const SkinInfluences& s, float threshold, std::pair<std::uint16_t, float>* out) {
  int n = 0;
  for (int i = 0; i < kMaxInfluences; ++i) {
    if (s.weights[i] > 0.0f && s.weights[i] >= threshold) out[n++] = {s.joints[i], s.weights[i]};
  }
  std::sort(out, out + n);
  return n;
}

int dominant_joint(const std::pair<std::uint16_t, float>* p, int n) {
  int best = -1;
  for (int i = 0; i < n; ++i) {
    if (best < 0 || p[i].second > p[best].second) best = i;
  }
  return best < 0 ? -1 : static_cast<int>(p[best].first);
}

}  // namespace

SkinComparison compare_skin(const SkinInfluences& x, const SkinInfluences& y, float threshold) {
  std::pair<std::uint16_t, float> a[kMaxInfluences], b[kMaxInfluences];
  const int na = significant_influences(x, threshold, a), nb = significant_influences(y, threshold, b);
  SkinComparison c;
  c.same_dominant = dominant_joint(a, na) == dominant_joint(b, nb);
  int i = 0, j = 0;
  while (i < na || j < nb) {
    double d = 0.0;
    if (j >= nb || (i < na && a[i].first < b[j].first)) {
      d = a[i++].second;
    } else if (i >= na || b[j].first < a[i].first) {
      d = b[j++].second;
    } else {
      d = static_cast<double>(a[i++].second) - static_cast<double>(b[j++].second);
    }
    c.l1 += std::abs(d);
    c.l2sq += d * d;
  }
  return c;
}

}  // namespace lodforge
