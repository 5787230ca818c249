// SimplifyOptions::stop: every engine polls it and returns the mesh as far as it got with StopReason::stopped.
// No timing here: an expired deadline, or a flag raised by the caller's stop policy (which the engines consult
// once a round, right after their own poll), decides where each run stops.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>

#include "lodforge/core/validate.hpp"
#include "lodforge/simplify/simplify.hpp"
#include "simplify_fixtures.hpp"
#include "test_support.hpp"

namespace lodforge {
namespace {

using simplify_test::make_bumpy_sphere;

StopRequest expired() { return {.deadline = StopRequest::Clock::now() - std::chrono::seconds(1)}; }

TEST(SimplifyStop, ExpiredDeadlineStopsEveryEngineBeforeAnyCollapse) {
  const Mesh sphere = make_bumpy_sphere(40, 60);
  const Mesh quads = testing::make_grid(40, 40, true);
  for (const Engine engine : {Engine::edge_collapse, Engine::multiple_choice, Engine::polychord}) {
    SCOPED_TRACE(static_cast<int>(engine));
    const Mesh& input = engine == Engine::polychord ? quads : sphere;
    SimplifyOptions options{.target_ratio = 0.1, .engine = engine};
    options.stop = expired();
    const SimplifyResult r = simplify(input, options);
    EXPECT_EQ(r.stop_reason, StopReason::stopped);
    EXPECT_STREQ(stop_reason_name(r.stop_reason), "stopped");
    EXPECT_EQ(r.collapses, 0u);
    EXPECT_EQ(r.triangles_after, r.triangles_before);
    EXPECT_TRUE(validate(r.mesh).ok());
    // With an error budget the measurement and back-off are skipped too.
    options.max_error_rel = 0.001;
    const SimplifyResult b = simplify(input, options);
    EXPECT_EQ(b.stop_reason, StopReason::stopped);
    EXPECT_FALSE(b.budget.verified);
    EXPECT_EQ(b.collapses, 0u);
  }
}

TEST(SimplifyStop, FlagRaisedMidRunStopsAtTheNextRound) {
  const Mesh sphere = make_bumpy_sphere(40, 60);
  for (const Engine engine : {Engine::edge_collapse, Engine::multiple_choice}) {
    SCOPED_TRACE(static_cast<int>(engine));
    std::atomic<bool> flag = false;
    SimplifyOptions options{.target_ratio = 0.1, .engine = engine};
    options.stop = {.flag = &flag};
    std::size_t polls_after_raise = 0;
    const CollapsePolicies policies{.stop = [&](const StopState& s) {
      if (flag) ++polls_after_raise;
      if (s.collapses > 0) flag = true;
      return false;
    }};
    const SimplifyResult r = simplify(sphere, options, policies);
    EXPECT_EQ(r.stop_reason, StopReason::stopped);
    EXPECT_GT(r.collapses, 0u);
    EXPECT_GT(r.triangles_after, r.triangles_before / 10);
    EXPECT_EQ(polls_after_raise, 0u) << "the engine stopped at its first poll after the flag was raised";
    EXPECT_TRUE(validate(r.mesh).ok());
  }
}

// Without a stop request (or with one never raised) the output is that of a run without it.
TEST(SimplifyStop, UnraisedRequestChangesNothing) {
  const Mesh sphere = make_bumpy_sphere(30, 40);
  std::atomic<bool> flag = false;
  for (const Engine engine : {Engine::edge_collapse, Engine::multiple_choice}) {
    SimplifyOptions plain{.target_ratio = 0.2, .engine = engine};
    SimplifyOptions polled = plain;
    polled.stop = {.deadline = StopRequest::Clock::now() + std::chrono::hours(24), .flag = &flag};
    const SimplifyResult a = simplify(sphere, plain), b = simplify(sphere, polled);
    EXPECT_EQ(b.stop_reason, StopReason::target_reached);
    EXPECT_EQ(a.mesh.positions, b.mesh.positions);
    EXPECT_EQ(a.mesh.corner_wedge, b.mesh.corner_wedge);
  }
}

}  // namespace
}  // namespace lodforge
