// The seams of the triangle engines (edge_collapse and multiple_choice), in the spirit of CGAL's
// Surface_mesh_simplification policies but as plain function objects: one placement, one cost, a filter (veto),
// a stop predicate and an observer. Every member is optional; an empty one leaves the built-in behaviour, and
// with all of them empty the engines run exactly as without policies.
//
//   CollapsePolicies p{.filter = [&](const CollapseCandidate& c) { return !keep[c.u] && !keep[c.v]; }};
//   SimplifyResult r = simplify(mesh, {.target_ratio = 0.1}, p);
//
// Everything a policy sees is in model units and input vertex ids. Policies are called from worker threads
// (placement, cost, filter) and must not depend on call order: the engines call them for the same candidates
// whatever the thread count, so a pure function keeps the output deterministic. The polychord engine's quad
// phase does not use them; its triangle continuation does.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>

#include "lodforge/core/vec.hpp"

namespace lodforge {

// A candidate collapse of edge (u, v), u < v, as the built-in metric sees it.
struct CollapseCandidate {
  std::uint32_t u = 0, v = 0;
  Vec3d position_u{}, position_v{};  // where the endpoints are now
  Vec3d position{};                  // where the survivor goes (after the placement policy)
  double cost = 0;                   // the built-in ordering key at `position` (cost policy: before it)
  double error = 0;                  // the built-in error at `position`: an area-weighted RMS plane distance
};

// A committed collapse, in commit order.
struct CollapseEvent {
  std::uint32_t victim = 0, survivor = 0;  // the victim disappears; the survivor moves to `position`
  Vec3d position{};
  double error = 0;               // as CollapseCandidate::error
  std::size_t triangles = 0;      // triangles left after it
};

// Where the engine stands between rounds (a round commits a batch of independent collapses).
struct StopState {
  std::size_t triangles = 0;
  std::size_t collapses = 0;
  std::size_t rounds = 0;
  double max_error = 0;  // largest committed CollapseCandidate::error so far
};

struct CollapsePolicies {
  // Where the survivor of a free edge goes (pinned endpoints still keep theirs); nullopt: the built-in
  // placement (the quadric's minimiser). `candidate.cost` and `.error` are not yet filled in.
  std::function<std::optional<Vec3d>(const CollapseCandidate&)> placement{};
  // The ordering key, lower first; negative values count as 0. The error budget still uses the built-in error.
  std::function<double(const CollapseCandidate&)> cost{};
  // false refuses the collapse (counted as Veto::filter); asked after the built-in checks passed, with the
  // candidate's position (its cost and error are left 0).
  std::function<bool(const CollapseCandidate&)> filter{};
  // true stops the engine before the next round (besides the target and the error budget).
  std::function<bool(const StopState&)> stop{};
  // Called for every committed collapse, in commit order, from the thread that runs the engine.
  std::function<void(const CollapseEvent&)> on_collapse{};

  bool any() const { return placement || cost || filter || stop || on_collapse; }
};

}  // namespace lodforge
