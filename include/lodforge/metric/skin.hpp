// Comparing the skin weights of two vertices: the rule every engine applies before merging vertices of a
// skinned mesh. Two vertices bound mostly to different joints separate when the
// skeleton moves, so merging them folds the LOD under animation; inside a joint's blend band the weights
// change gradually and neighbouring vertices may merge.
#pragma once

#include "lodforge/core/mesh.hpp"

namespace lodforge {

// Dominant joints (largest weight at or above the threshold; ties: the lower joint id) and the L1 and squared
// L2 distances of two weight vectors over the union of their joints, ignoring influences below `threshold`.
struct SkinComparison {
  bool same_dominant = true;
  double l1 = 0, l2sq = 0;
};
SkinComparison compare_skin(const SkinInfluences& x, const SkinInfluences& y, float threshold);

// Whether two vertices may merge: same dominant joint, or weight vectors closer than `max_l1` (the blend band).
inline bool skin_mergeable(const SkinInfluences& x, const SkinInfluences& y, double threshold, double max_l1) {
  const SkinComparison c = compare_skin(x, y, static_cast<float>(threshold));
  return c.same_dominant || c.l1 < max_l1;
}

}  // namespace lodforge
