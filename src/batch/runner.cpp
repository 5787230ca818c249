// The batch runner: a oneTBB flow graph over the assets of a library.
//
//   admission ─► fingerprint ─► load ─► analyse ─► lods ─► post_process ─┬► measure ─► write ─┬► gather ─► report
//       ▲                                                                   └──► pictures ───────┘    (serial) │
//       └──────────────────────── the finished asset's memory goes back to the budget ─────────────────────────┘
//
// The report's pictures of the LODs are drawn beside measure and write (they read the same meshes, and write
// nothing of the Job's but their own fields); gather passes a job on when both branches are done with it, and
// publishes the pictures of an asset that succeeded.
//
// Every stage is a function_node over a shared Job. A stage that throws marks its Job finished (failed) and
// the later stages pass it through untouched, so one bad asset never stops the graph. Admission is a small
// gate in front of the graph, not a limiter_node: limiter_node counts messages, while the budget here is in
// bytes (an asset's estimated footprint), and one oversized asset must still be able to run alone. The gate is
// opened from the serial report node each time an asset finishes, so no thread ever blocks waiting for memory.
//
// Determinism: each asset's outputs depend only on its file, its class and the config (and the memory limit, for
// an asset estimated over the budget: its LODs are tiled to fit); the simplifier and eval
// give identical results for any thread count; records are collected by library index, not completion order.
#include "lodforge/batch/runner.hpp"

#include <tbb/collaborative_call_once.h>
#include <tbb/flow_graph.h>
#include <tbb/global_control.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <unistd.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <algorithm>
#include <bit>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <deque>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>

#include "lodforge/batch/cache.hpp"
#include "lodforge/batch/lods_manifest.hpp"
#include "lodforge/batch/post_process.hpp"
#include "lodforge/batch/report.hpp"
#include "lodforge/core/topology.hpp"
#include "lodforge/core/validate.hpp"
#include "lodforge/core/volume.hpp"
#include "lodforge/eval/attribute_eval.hpp"
#include "lodforge/eval/distance_bound.hpp"
#include "lodforge/eval/eval.hpp"
#include "lodforge/io/asset.hpp"
#include "lodforge/io/file.hpp"
#include "lodforge/io/heightmap.hpp"
#include "lodforge/io/lods.hpp"
#include "lodforge/io/picture.hpp"
#include "lodforge/quad/quad_stats.hpp"
#include "lodforge/simplify/simplify.hpp"
#include "lodforge/symmetry/symmetry.hpp"
#include "lodforge/tiling/terrain.hpp"
#include "lodforge/tiling/tiling.hpp"

namespace lodforge::batch {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;
using Clock = std::chrono::steady_clock;

// Meshes below this many triangles are simplified and measured on one thread: their whole chain takes a few
// milliseconds, less than waking a team of threads, and the graph keeps the other cores busy with other assets.
constexpr std::size_t kParallelTriangles = 20000;
// Eval samples per direction: 2 per triangle of the larger mesh, within [2000, 100000]. Far below eval's own
// default (which is made for accuracy studies): the report needs the error to a few per cent, and measuring
// must not cost more than simplifying.
constexpr std::size_t kEvalSamplesPerTriangle = 1, kEvalSamplesMin = 500, kEvalSamplesMax = 50000;
// Attribute metrics (attribute_metrics()): area samples per source triangle, clamped, and per synthetic pose.
constexpr std::size_t kAttributeSamplesPerTriangle = 2, kAttributeSamplesMin = 2000, kAttributeSamplesMax = 50000;
constexpr std::size_t kAttributePoseSamples = 5000;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// JSON cannot hold inf/NaN (nlohmann writes null); the report's numbers stay numbers.
double finite(double x) {
  if (std::isnan(x)) return 0.0;
  if (std::isinf(x)) return x > 0 ? std::numeric_limits<double>::max() : std::numeric_limits<double>::lowest();
  return x;
}

// Resident memory of this process now (VmRSS), 0 when /proc is not there.
std::uint64_t asset_bytes(const fs::path& file);

// Bytes of the regular files under `dir` (an asset's written outputs, report.json "output_bytes").
std::uint64_t tree_bytes(const fs::path& dir) {
  std::uint64_t bytes = 0;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::recursive_directory_iterator();
       it.increment(ec)) {
    std::error_code size_ec;
    if (it->is_regular_file(size_ec)) {
      const std::uintmax_t n = it->file_size(size_ec);
      if (!size_ec) bytes += n;
    }
  }
  return bytes;
}

std::uint64_t resident_bytes() {
  std::ifstream statm("/proc/self/statm");
  std::uint64_t size = 0, resident = 0;
  if (!(statm >> size >> resident)) return 0;
  return resident * static_cast<std::uint64_t>(::sysconf(_SC_PAGESIZE));
}

// Hands freed heap memory back to the OS. glibc keeps freed chunks in its arenas (one per thread), so without
// this the resident size after a large asset stays at its peak and the admission's resident check would see
// memory nobody uses. Not after the smallest assets (footprint ~ kFootprintOverhead): trimming walks every
// arena, which would cost more than such an asset's whole chain.
constexpr std::uint64_t kTrimAfterFootprint = 2u << 20;
void release_free_memory() {
#if defined(__GLIBC__)
  ::malloc_trim(0);
#endif
}

// Thrown where an asset is found past its deadline; the stage wrapper turns it into the asset's failure.
struct TimedOut {};

// ---- per-mesh LOD chains, shared by duplicates ----------------------------------------------------------------

struct MeshLod {
  Mesh mesh;
  // Against the source: measured when an error budget was verified (budget), else the QEM errors
  // accumulated along "previous" links (a ranking, not a bound).
  double error_bound_abs = 0;
  BudgetCheck budget;
  StopReason stop = StopReason::target_reached;
  std::vector<std::string> floors{};  // SimplifyResult::floors: what held a missed target
  SeamStage seam_stage = SeamStage::strict;
  double seconds = 0;
  std::size_t conservative_refused = 0;  // conservative LODs: collapses the nesting rule refused
  // The asset was over the run's memory budget: the tile size this LOD was cut into to fit it (0: it ran
  // untiled), or why it could not be and ran over the budget.
  std::size_t memory_tile_triangles = 0;
  std::string memory_over{};
};
using MeshChain = std::vector<MeshLod>;

using tiling::mesh_bytes;

// Duplicate meshes (same content, class and asset context) share one chain. The first asset to need a chain
// builds it inside tbb::collaborative_call_once, so a duplicate arriving meanwhile joins that work instead of
// blocking a thread or building it again. Finished chains are kept while they fit `capacity_bytes` (oldest
// evicted first), because a library can hold many more distinct meshes than memory.
class ChainTable {
 public:
  explicit ChainTable(std::size_t capacity_bytes) : capacity_(capacity_bytes) {}

  std::shared_ptr<const MeshChain> get(const std::string& key, const std::function<MeshChain()>& build) {
    std::shared_ptr<Slot> slot;
    {
      std::lock_guard lock(mutex_);
      auto& s = slots_[key];
      if (!s) s = std::make_shared<Slot>();
      slot = s;
    }
    bool built = false;
    tbb::collaborative_call_once(slot->flag, [&] {
      slot->chain = std::make_shared<const MeshChain>(build());
      built = true;
    });
    if (built) retain(key, *slot->chain);
    return slot->chain;
  }

 private:
  struct Slot {
    tbb::collaborative_once_flag flag;
    std::shared_ptr<const MeshChain> chain;
  };

  void retain(const std::string& key, const MeshChain& chain) {
    std::size_t bytes = 0;
    for (const MeshLod& l : chain) bytes += mesh_bytes(l.mesh);
    std::lock_guard lock(mutex_);
    order_.emplace_back(key, bytes);
    held_ += bytes;
    while (held_ > capacity_ && order_.size() > 1) {
      slots_.erase(order_.front().first);  // holders keep their shared_ptr; later copies rebuild
      held_ -= order_.front().second;
      order_.pop_front();
    }
  }

  std::mutex mutex_;
  std::map<std::string, std::shared_ptr<Slot>> slots_;
  std::deque<std::pair<std::string, std::size_t>> order_;
  std::size_t held_ = 0, capacity_;
};

// Content hash of everything in a Mesh except its name (two copies of a mesh under different names are
// duplicates; the name is put back on the LODs).
std::string mesh_content_hash(const Mesh& m) {
  Hasher h;
  h.array(m.positions).array(m.skin).array(m.priority).array(m.wedge_vertex).array(m.normals).array(m.tangents);
  h.u64(m.uvs.size());
  for (const auto& s : m.uvs) h.array(s);
  h.u64(m.colors.size());
  for (const auto& s : m.colors) h.array(s);
  h.array(m.color_components);
  h.u64(m.custom.size());
  for (const CustomAttribute& c : m.custom) {
    h.bytes(c.name)
        .u64(static_cast<std::uint64_t>(c.components))
        .u64(static_cast<std::uint64_t>(c.format.component_type));
    h.u64(c.format.normalized).array(c.values);
  }
  h.u64(m.morph_targets.size());
  for (const MorphTarget& t : m.morph_targets) {
    h.bytes(t.name).array(t.position_deltas).array(t.normal_deltas).array(t.tangent_deltas);
  }
  h.array(m.morph_default_weights).array(m.face_offsets).array(m.corner_wedge).array(m.face_material);
  h.array(m.face_group);
  h.u64(m.materials.size());
  for (const MaterialSlot& s : m.materials) {
    h.bytes(s.name)
        .u64(static_cast<std::uint64_t>(s.gltf_material))
        .u64(static_cast<std::uint64_t>(s.source_primitive));
    h.u64(s.has_normals).u64(s.has_tangents).u64(static_cast<std::uint64_t>(s.uv_sets));
    h.u64(static_cast<std::uint64_t>(s.color_sets)).u64(s.has_custom).u64(s.has_morphs);
  }
  h.u64(m.groups.size());
  for (const std::string& g : m.groups) h.bytes(g);
  for (const auto& [semantic, format] : m.formats) {
    h.bytes(semantic).u64(static_cast<std::uint64_t>(format.component_type)).u64(format.normalized);
  }
  return h.hex();
}

unsigned threads_for(std::size_t triangles, unsigned jobs) {
  return triangles < kParallelTriangles ? 1 : jobs;
}

// An asset over the run's memory budget runs alone; each of its simplifications is planned against what is left
// of the budget (`limit`) once the meshes it holds besides the input (`held`) are counted, and tiled where an
// untiled run would not fit. A plan that cannot fit either says why, and the run goes on untiled.
void fit_memory(const Mesh& from, std::optional<std::uint64_t> limit, std::uint64_t held, SimplifyOptions& options,
                MeshLod& lod) {
  if (!limit) return;
  const std::size_t left = *limit > held ? static_cast<std::size_t>(*limit - held) : 0;
  const tiling::MemoryPlan plan = tiling::plan_memory(from, options, left, std::max(options.threads, 1u));
  if (plan.force_tiling) {
    plan.apply(options);
    lod.memory_tile_triangles = plan.tile_triangles;
  } else if (!plan.fits) {
    const char* why = tiling::why_not_tileable(options);
    lod.memory_over = "about " + std::to_string(plan.untiled_bytes >> 20) + " MiB untiled, over the " +
                      std::to_string(left >> 20) + " MiB left of the memory budget, and " +
                      (why != nullptr ? std::string(why) : std::string("tiles small enough would not fit either")) +
                      ": ran untiled";
  }
}

// One mesh's chain. Ratios are of the mesh's own triangles; a triangle-count target is the asset's, shared
// among its meshes by their triangle counts; error targets are relative to the asset's diagonal.
// `expire` (testing aid, null normally): set just before the first simplify() call, so that only the engine's
// own polling of `stop` (which reads it) can time the asset out.
// `memory_limit` (none: no limit) and `held`: as fit_memory(), `held` counting what the asset holds besides this
// mesh.
MeshChain build_chain(const Mesh& source, const AssetClass& cls, std::size_t asset_triangles, double asset_diagonal,
                      unsigned jobs, const StopRequest& stop, std::optional<std::uint64_t> memory_limit = {},
                      std::uint64_t held = 0, std::atomic<bool>* expire = nullptr) {
  MeshChain chain;
  const std::size_t source_triangles = source.triangle_count();
  std::optional<SurfaceIndex> source_index;  // the chained LODs' budgets measure against it: built once
  std::vector<std::uint32_t> attachments;    // the last LOD's SimplifyResult::reference_attachments
  for (std::size_t k = 0; k < cls.lods.size(); ++k) {
    if (stop.requested()) throw TimedOut{};  // the engines poll it too; this spares a doomed LOD's setup
    LodSpec spec = cls.lods[k];
    const bool chained = spec.from == LodFrom::previous && k > 0;
    const Mesh& from = chained ? chain[k - 1].mesh : source;
    // An error budget is measured against the source itself, so nothing is spent by the LODs before it.
    const bool error_target = spec.target.kind == TargetKind::max_error_rel ||
                              spec.target.kind == TargetKind::max_error_abs ||
                              spec.target.kind == TargetKind::screen_size;
    const double spent = chained && !error_target ? chain[k - 1].error_bound_abs : 0.0;
    if (spec.target.kind == TargetKind::triangles && asset_triangles > 0) {
      const double share = static_cast<double>(spec.target.triangles) * static_cast<double>(source_triangles) /
                           static_cast<double>(asset_triangles);
      spec.target.triangles = std::max<std::size_t>(1, static_cast<std::size_t>(std::llround(share)));
    }
    SimplifyOptions options = simplify_options_for(spec, LodInput{.source_triangles = source_triangles,
                                                                  .source_diagonal = asset_diagonal,
                                                                  .accumulated_error_abs = spent});
    options.threads = threads_for(from.triangle_count(), jobs);
    if (chained) {
      options.budget_reference = &source;
      if (options.verifies_budget()) {
        if (!source_index) source_index.emplace(source);
        options.budget_reference_index = &*source_index;
        // The previous LOD's guard kept every sample of the source near one of its triangles: a start.
        if (!attachments.empty()) options.budget_attachments = &attachments;
      }
    }
    options.stop = stop;
    MeshLod lod;
    std::uint64_t chain_bytes = chained ? mesh_bytes(source) : 0;  // `from` itself is the plan's input
    for (std::size_t j = 0; j + (chained ? 1 : 0) < k; ++j) chain_bytes += mesh_bytes(chain[j].mesh);
    fit_memory(from, memory_limit, held + chain_bytes, options, lod);
    if (expire != nullptr) expire->store(true);
    const auto t0 = Clock::now();
    SimplifyResult r = simplify_maybe_tiled(from, options);
    if (r.stop_reason == StopReason::stopped) throw TimedOut{};
    attachments = std::move(r.reference_attachments);
    lod.mesh = std::move(r.mesh);
    lod.mesh.name = source.name;
    lod.error_bound_abs = r.budget.verified ? r.budget.bound_abs : spent + r.qem_error_abs;
    lod.budget = r.budget;
    lod.stop = r.stop_reason;
    lod.floors = std::move(r.floors);
    lod.seam_stage = r.seam_stage;
    lod.seconds = seconds_since(t0);
    chain.push_back(std::move(lod));
  }
  return chain;
}

// One mesh's collision and occluder LODs (the class's `conservative` entries, in order), each built from the
// source. Targets are shared among the asset's meshes as in build_chain. A failure names the entry.
std::vector<MeshLod> build_conservative(const Mesh& source, const AssetClass& cls, std::size_t asset_triangles,
                                        double asset_diagonal, unsigned jobs, const StopRequest& stop,
                                        std::optional<std::uint64_t> memory_limit = {}, std::uint64_t held = 0) {
  std::vector<MeshLod> out;
  const std::size_t source_triangles = source.triangle_count();
  for (ConservativeSpec spec : cls.conservative) {
    if (stop.requested()) throw TimedOut{};
    if (spec.target && spec.target->kind == TargetKind::triangles && asset_triangles > 0) {
      const double share = static_cast<double>(spec.target->triangles) * static_cast<double>(source_triangles) /
                           static_cast<double>(asset_triangles);
      spec.target->triangles = std::max<std::size_t>(1, static_cast<std::size_t>(std::llround(share)));
    }
    SimplifyOptions options = simplify_options_for(
        spec,
        LodInput{.source_triangles = source_triangles, .source_diagonal = asset_diagonal, .accumulated_error_abs = 0});
    options.threads = threads_for(source_triangles, jobs);
    options.stop = stop;
    MeshLod lod;
    std::uint64_t built_bytes = held;
    for (const MeshLod& l : out) built_bytes += mesh_bytes(l.mesh);
    fit_memory(source, memory_limit, built_bytes, options, lod);
    const auto t0 = Clock::now();
    std::optional<SimplifyResult> r;
    try {
      r.emplace(simplify_maybe_tiled(source, options));
    } catch (const std::exception& e) {
      throw std::runtime_error(std::string("the ") + conservative_kind_name(spec.kind) + " LOD: " + e.what());
    }
    if (r->stop_reason == StopReason::stopped) throw TimedOut{};
    lod.mesh = std::move(r->mesh);
    lod.mesh.name = source.name;
    lod.error_bound_abs = r->budget.verified ? r->budget.bound_abs : r->qem_error_abs;
    lod.budget = r->budget;
    lod.stop = r->stop_reason;
    lod.floors = std::move(r->floors);
    lod.seam_stage = r->seam_stage;
    lod.seconds = seconds_since(t0);
    lod.conservative_refused = r->vetoes[Veto::conservative];
    out.push_back(std::move(lod));
  }
  return out;
}

// ---- jobs and admission ---------------------------------------------------------------------------------------

double work_seconds(const StageSeconds& s) {
  return s.fingerprint + s.load + s.analyse + s.lods + s.post_process + s.measure + s.write;
}

struct Job {
  std::size_t index = 0;
  std::string path;  // relative, '/'-separated
  fs::path file;
  const AssetClass* cls = nullptr;
  std::uint64_t footprint = 0;

  bool finished = false;  // failed or cache hit: later stages pass the job through
  Json record;
  std::string key;
  StageSeconds stages;
  std::uint64_t processed_triangles = 0;  // input triangles when the asset was really processed

  io::Asset asset;
  std::size_t triangles = 0, vertices = 0;
  std::size_t repeated_faces = 0;  // faces repeating an earlier one in the input, dropped before simplifying
  double diagonal = 0;
  std::vector<std::shared_ptr<const MeshChain>> chains;  // per asset mesh
  std::vector<Mesh> sources;                             // per asset mesh, post-processed for output
  std::vector<std::vector<Mesh>> levels;                 // [level][mesh], post-processed
  std::vector<double> coverage;                          // MSFT_screencoverage, levels + 1 values
  std::vector<bool> shows_previous;                      // per level: a near-copy of the one before, not stored
  std::vector<std::vector<MeshLod>> conservative_built;  // [mesh][entry]: the class's collision/occluder LODs
  std::vector<std::vector<Mesh>> conservative;           // [entry][mesh], post-processed for output
  // A terrain class's height map: the patches' chains until the lods stage takes them (the asset's meshes are
  // the patches' full-resolution surfaces), and per level (0 = the source) and asset mesh the triangles without
  // the skirts, which the ratio targets count (empty for a mesh asset).
  std::optional<terrain::Result> terrain;
  std::vector<std::vector<std::size_t>> terrain_surface;  // [level][mesh]
  std::size_t terrain_surface_total(std::size_t level) const {
    std::size_t n = 0;
    for (const std::size_t t : terrain_surface[level]) n += t;
    return n;
  }

  // The report's pictures (PNG bytes, the source first, then each level). Only the picture branch touches
  // them, and only until both branches after post-process have arrived at gather.
  bool picture_wanted = false;
  std::vector<std::string> picture_png;
  std::string picture_error;
  std::atomic<int> arrivals{2};  // branches after post-process still running; the last one passes the job on

  // RunLimits::asset_timeout_s after the first stage started; none without a limit.
  std::optional<Clock::time_point> deadline;
  // Set by RunOptions::expire_in_simplify (testing aid): stop_request() then reads as past the deadline.
  std::atomic<bool> expired{false};
  bool expired_at_stage = false;  // set by RunOptions::expire_on_stage (testing aid)
  bool past_deadline() const { return expired_at_stage || (deadline && Clock::now() > *deadline); }
  void check_deadline() const {
    if (past_deadline()) throw TimedOut{};
  }
  // The same test for the long loops inside a stage (the simplifier's rounds, eval's sampling).
  StopRequest stop_request() const {
    return {.deadline = deadline ? *deadline : StopRequest::Clock::time_point::max(), .flag = &expired};
  }
};
using JobPtr = std::shared_ptr<Job>;

struct Pending {
  std::size_t index = 0;
  std::string path;
  const AssetClass* cls = nullptr;
  std::uint64_t footprint = 0;
};

// Which assets may start: in library order, while the footprints in flight fit the budget and the process's
// resident memory plus the next footprint fits the limit. The first check plans (an asset in flight has not
// reached its peak yet); the second sees what the plan misses (memory the allocator has not returned, the
// duplicate-chain cache, an estimate that was low). Either way one asset is always allowed, so the run
// progresses; which assets run together never changes what they produce.
class Admission {
 public:
  Admission(std::vector<Pending> pending, std::uint64_t budget, std::uint64_t limit, std::size_t max_in_flight,
            const std::atomic<bool>* cancel, std::size_t stop_after)
      : pending_(std::move(pending)),
        budget_(budget),
        limit_(limit),
        max_in_flight_(max_in_flight),
        cancel_(cancel),
        stop_after_(stop_after) {}

  std::vector<Pending> take() {
    std::lock_guard lock(mutex_);
    std::vector<Pending> out;
    std::optional<std::uint64_t> resident;  // read once per call, only when an asset is already in flight
    while (next_ < pending_.size()) {
      if ((cancel_ && cancel_->load()) || (stop_after_ && admitted_ >= stop_after_)) break;
      const std::uint64_t fp = pending_[next_].footprint;
      if (in_flight_ > 0) {
        if (in_flight_ >= max_in_flight_ || reserved_ + fp > budget_) break;
        if (!resident) resident = resident_bytes();
        if (*resident + fp > limit_) break;
        *resident += fp;
      }
      reserved_ += fp;
      ++in_flight_;
      ++admitted_;
      out.push_back(pending_[next_++]);
    }
    return out;
  }

  void release(std::uint64_t footprint) {
    std::lock_guard lock(mutex_);
    reserved_ -= footprint;
    --in_flight_;
  }

  // Assets never admitted (the run was stopped), in library order.
  std::vector<Pending> left() const {
    std::lock_guard lock(mutex_);
    return {pending_.begin() + static_cast<std::ptrdiff_t>(next_), pending_.end()};
  }

 private:
  mutable std::mutex mutex_;
  std::vector<Pending> pending_;
  std::size_t next_ = 0, in_flight_ = 0, admitted_ = 0;
  std::uint64_t reserved_ = 0;
  std::uint64_t budget_, limit_;
  std::size_t max_in_flight_;
  const std::atomic<bool>* cancel_;
  std::size_t stop_after_;
};

// ---- report records -------------------------------------------------------------------------------------------

Json base_record(const std::string& path, const AssetClass* cls) {
  return {{"path", path},
          {"class", cls ? Json(cls->name) : Json(nullptr)},
          {"status", "ok"},
          {"error", nullptr},
          {"cache_hit", false},
          {"seconds", 0.0},
          {"input", {{"triangles", 0}, {"vertices", 0}, {"diagonal", 0.0}}},
          {"outputs", Json::array()},
          {"lods", Json::array()}};
}

Json target_json(const LodTarget& t) {
  switch (t.kind) {
    case TargetKind::ratio:
      return {{"kind", "ratio"}, {"value", t.ratio}};
    case TargetKind::triangles:
      return {{"kind", "triangles"}, {"value", static_cast<double>(t.triangles)}};
    case TargetKind::max_error_rel:
    case TargetKind::max_error_abs:
      return {{"kind", "max_error"}, {"value", t.max_error}};
    case TargetKind::screen_size:
      return {{"kind", "screen_size"}, {"value", t.screen.pixels}};
  }
  return nullptr;
}

Json target_triangles_json(const LodTarget& t, std::size_t source_triangles) {
  if (t.kind == TargetKind::ratio) {
    return std::max<std::size_t>(1, static_cast<std::size_t>(std::llround(t.ratio * double(source_triangles))));
  }
  if (t.kind == TargetKind::triangles) return t.triangles;
  return nullptr;
}

std::string joined(const std::vector<std::string>& items) {
  std::string out;
  for (const std::string& i : items) out += (out.empty() ? "" : ", ") + i;
  return out;
}

// Whether a LOD met what its spec asked, and why not (report.json "budget"): a ratio or triangle target within
// 2% (a miss names the floors that held it, SimplifyResult::floors), an error budget held by measurement
// (collapses backed off to hold it are said, not a miss), and a LOD at least 10% smaller than the level
// before (else it is close to a copy of it).
Json budget_json(const LodTarget& t, std::size_t source_triangles, std::size_t triangles, std::size_t previous,
                 std::size_t level, const std::set<std::string>& stops, bool error_met, std::size_t backed_off,
                 bool shows_previous, const std::vector<std::string>& floors) {
  Json reasons = Json::array();
  std::string why_stopped;
  for (const std::string& s : stops) {
    if (s != "target_reached") why_stopped += (why_stopped.empty() ? "" : ", ") + s;
  }
  const bool error_target =
      t.kind == TargetKind::max_error_rel || t.kind == TargetKind::max_error_abs || t.kind == TargetKind::screen_size;
  if (error_target) {
    if (!error_met) reasons.push_back("error budget not met by measurement");
  } else if (const Json target = target_triangles_json(t, source_triangles); target.is_number()) {
    const double allowed = std::ceil(1.02 * target.get<double>());
    if (static_cast<double>(triangles) > allowed) {
      reasons.push_back("target not reached: " + std::to_string(triangles) + " triangles for " +
                        std::to_string(target.get<std::size_t>()) +
                        (why_stopped.empty() ? std::string() : " (stopped: " + why_stopped + ")") +
                        (floors.empty() ? std::string() : "; floor: " + joined(floors)));
    }
  }
  if (shows_previous || (triangles > 0 && 10 * triangles > 9 * previous)) {
    reasons.push_back("not 10% smaller than " +
                      (level == 0 ? std::string("the source") : "LOD " + std::to_string(level)) +
                      (shows_previous ? ": shows its meshes" : ""));
  }
  Json out{{"status", reasons.empty() ? "met" : "missed"}, {"reasons", std::move(reasons)}};
  if (error_target) out["collapses_backed_off"] = backed_off;
  return out;
}

// The LOD record's "attributes" object, name -> number: the face-normal deviation of the surface samples
// (from the position eval), then, from evaluate_attributes per asset mesh (source mesh m against LOD mesh m;
// meshes folded together: counts summed, errors and ratios their maximum): "rms.<STREAM>" the RMS error of each
// attribute stream at the closest point ("rms.NORMAL", "rms.TEXCOORD_0", "rms.COLOR_0"), "interpolated_normal_
// deviation_p95_deg", "uv_flipped" and "uv_spanning" triangle counts over all UV sets, "uv_stretch_ratio" (LOD
// stretch / source stretch, worst set), and for skinned meshes "pose_hausdorff_rel" (worst synthetic pose).
// Sample counts are capped (kAttributeSamples*) so that small assets stay cheap.
Json attribute_metrics(const EvalResult& e, const std::vector<Mesh>& sources, const std::vector<Mesh>& lods,
                       unsigned jobs, const StopRequest& stop) {
  Json out = {{"normal_deviation_mean_deg", finite(e.normal_deviation_mean_deg)},
              {"normal_deviation_p95_deg", finite(e.normal_deviation_p95_deg)}};
  std::map<std::string, double> rms;
  double normal_p95 = 0, stretch = 0, pose = 0;
  std::size_t flipped = 0, spanning = 0;
  bool has_uv = false, has_normals = false, skinned = false;
  for (std::size_t m = 0; m < sources.size() && m < lods.size(); ++m) {
    const Mesh& source = sources[m];
    const Mesh& lod = lods[m];
    const std::size_t triangles = source.triangle_count();
    if (triangles == 0 || lod.triangle_count() == 0) continue;
    if (source.normals.empty() && source.uvs.empty() && source.colors.empty() && source.skin.empty()) {
      continue;  // nothing to measure
    }
    AttributeEvalOptions options;
    options.samples = std::clamp(kAttributeSamplesPerTriangle * triangles, kAttributeSamplesMin, kAttributeSamplesMax);
    options.pose_samples = kAttributePoseSamples;
    options.threads = threads_for(triangles, jobs);
    options.stop = stop;
    const AttributeEvalResult r = evaluate_attributes(source, lod, options);
    if (r.stopped) throw TimedOut{};
    for (const AttributeError& a : r.attributes) rms[a.name] = std::max(rms[a.name], a.rms);
    if (!source.normals.empty() && !lod.normals.empty()) {
      has_normals = true;
      normal_p95 = std::max(normal_p95, r.normal_deviation_p95_deg);
    }
    for (const UvSetReport& uv : r.uv_sets) {
      has_uv = true;
      stretch = std::max(stretch, uv.stretch_ratio);
      flipped += uv.flipped;
      spanning += uv.spanning;
    }
    if (!r.poses.empty()) {
      skinned = true;
      pose = std::max(pose, r.pose_max_hausdorff_rel);
    }
  }
  for (const auto& [name, value] : rms) out["rms." + name] = finite(value);
  if (has_normals) out["interpolated_normal_deviation_p95_deg"] = finite(normal_p95);
  if (has_uv) {
    out["uv_flipped"] = flipped;
    out["uv_spanning"] = spanning;
    out["uv_stretch_ratio"] = finite(stretch);
  }
  if (skinned) out["pose_hausdorff_rel"] = finite(pose);
  return out;
}

io::Asset with_meshes(const io::Asset& base, std::vector<Mesh> meshes) {
  io::Asset a;
  a.source = base.source;
  a.format = base.format;
  a.gltf = base.gltf;
  a.obj_mtllibs = base.obj_mtllibs;
  a.binary = base.binary;
  a.mesh_transforms = base.mesh_transforms;
  a.meshes = std::move(meshes);
  return a;
}

// report.json input.symmetry: the asset's edges found symmetric over all its meshes, and the plane of the mesh
// with the most of them (in that mesh's own coordinates), or null where none is.
Json symmetry_json(const std::vector<Mesh>& meshes, symmetry::PlaneMode mode) {
  std::size_t symmetric = 0, edges = 0, best = 0;
  Json plane = nullptr;
  for (const Mesh& mesh : meshes) {
    const symmetry::SymmetryMap s = symmetry::detect_symmetry(mesh, {.plane = mode});
    symmetric += s.symmetric_edges;
    edges += s.edges;
    if (s.symmetric_edges > best) {
      best = s.symmetric_edges;
      plane = Json::array(
          {finite(s.plane.normal[0]), finite(s.plane.normal[1]), finite(s.plane.normal[2]), finite(s.plane.offset)});
    }
  }
  return {{"plane_mode", symmetry::plane_mode_name(mode)},
          {"symmetric_edges", symmetric},
          {"edges", edges},
          {"fraction", edges == 0 ? 0.0 : static_cast<double>(symmetric) / static_cast<double>(edges)},
          {"plane", plane}};
}

bool is_gltf(io::Format f) {
  return f == io::Format::gltf || f == io::Format::glb;
}

// ---- the pipeline ---------------------------------------------------------------------------------------------

// A LOD of an asset over the memory budget: the tile size it was cut into (the largest of its meshes') and, once
// per asset, a warning where a mesh could not be fitted.
void note_memory(const MeshLod& built, const std::string& what, std::size_t& tile_triangles, Json& record) {
  tile_triangles = std::max(tile_triangles, built.memory_tile_triangles);
  if (built.memory_over.empty()) return;
  record["warnings"].push_back(what + ": " + built.memory_over);
}

class Pipeline {
 public:
  // `asset_budget`: the memory the assets in flight share (an asset estimated over it runs alone, and tiled).
  Pipeline(const BatchConfig& config, const RunOptions& options, const Cache& cache, unsigned jobs,
           std::uint64_t chain_cache_bytes, std::uint64_t asset_budget)
      : config_(config),
        options_(options),
        cache_(cache),
        jobs_(jobs),
        asset_budget_(asset_budget),
        chains_(chain_cache_bytes) {
    for (const AssetClass& cls : config.classes) class_json_[&cls] = effective_class_json(config, cls);
  }

  void fingerprint(Job& job) {
    job.key = cache_key(input_fingerprint(job.file), class_json_.at(job.cls), kAlgorithmVersion);
    if (options_.force) return;
    if (std::optional<Json> record = cache_.lookup(job.path, job.key)) {
      job.record = std::move(*record);
      job.record["cache_hit"] = true;
      job.finished = true;
    }
  }

  void load(Job& job) {
    if (job.cls->terrain) {
      load_terrain(job);
    } else {
      job.asset = io::load_asset(job.file);
    }
  }

  // A height map of a terrain class: cut into patches and simplified here (terrain::build makes every level
  // at once, its walls shared between patches); the asset is the patches' full-resolution surfaces, one mesh
  // each, written as glTF.
  void load_terrain(Job& job) {
    if (!io::is_heightmap_path(job.file)) {
      throw std::runtime_error("class \"" + job.cls->name +
                               "\" is a terrain class: it takes height maps (.png, .r16), not meshes");
    }
    const TerrainSpec& spec = *job.cls->terrain;
    const io::HeightMap map = io::load_heightmap(job.file, spec.layout);
    terrain::Options o;
    o.patch_cells = spec.patch_cells;
    o.conservative = spec.conservative;
    o.skirts = spec.skirts;
    o.threads = threads_for(2 * map.width * map.height, jobs_);
    o.levels.clear();
    for (const LodSpec& lod : job.cls->lods) o.levels.push_back({.ratio = lod.target.ratio, .max_error = -1.0});
    if (const std::vector<std::string> problems = o.validate(); !problems.empty()) {
      throw std::runtime_error("terrain: " + joined(problems));
    }
    // The last build of this map (the cache folder keeps it): patches whose samples did not change are copied
    // from it. Unreadable or from other settings, it only costs a full build.
    const fs::path saved = options_.output_dir / kCacheFolder / "terrain" / (Hasher().bytes(job.path).hex() + ".bin");
    std::optional<terrain::Result> previous;
    if (!options_.force) {
      try {
        previous = terrain::decode_result(io::read_file(saved));
      } catch (const io::IoError&) {
      }
    }
    job.terrain = terrain::build(map, o, previous ? &*previous : nullptr);
    previous.reset();
    if (const std::string bytes = terrain::encode_result(*job.terrain); !bytes.empty()) {
      std::error_code ec;
      fs::create_directories(saved.parent_path(), ec);
      try {
        io::write_file_atomic(saved, bytes, io::Durability::none);
      } catch (const io::IoError& e) {
        job.record["warnings"].push_back(std::string("terrain patches not kept for the next run: ") + e.what());
      }
    }
    job.asset = io::Asset{};
    job.asset.source = job.file;
    job.asset.format = io::Format::glb;
    job.terrain_surface.assign(o.levels.size() + 1, {});
    for (const terrain::Patch& p : job.terrain->patches) {
      if (p.lods[0].face_count() == 0) continue;  // all hole: nothing to show
      job.asset.meshes.push_back(p.lods[0]);
      for (std::size_t k = 0; k < p.surface_triangles.size(); ++k)
        job.terrain_surface[k].push_back(p.surface_triangles[k]);
    }
    Json surface = Json::array();
    for (std::size_t k = 0; k < job.terrain_surface.size(); ++k) surface.push_back(job.terrain_surface_total(k));
    job.record["terrain"] = {{"width", map.width},
                             {"height", map.height},
                             {"patches", {job.terrain->patches_x, job.terrain->patches_z}},
                             {"patch_cells", spec.patch_cells},
                             {"rebuilt_patches", job.terrain->rebuilt},
                             {"surface_triangles", std::move(surface)},
                             {"warnings", map.warnings}};
  }

  void analyse(Job& job) {
    for (std::size_t m = 0; m < job.asset.meshes.size(); ++m) {
      const Mesh& mesh = job.asset.meshes[m];
      const ValidationReport v = validate(mesh);
      // What the simplifier cannot survive is an error here; other findings (non-manifold, degenerate faces)
      // are what the simplifier is built to cope with.
      if (v.out_of_range_indices || v.nonfinite_positions || v.attribute_size_errors) {
        std::string why;
        for (const std::string& msg : v.messages) why += (why.empty() ? "" : "; ") + msg;
        throw std::runtime_error("mesh " + std::to_string(m) + " is invalid: " + why);
      }
      job.triangles += mesh.triangle_count();
      job.vertices += mesh.vertex_count();
      job.repeated_faces += repeated_faces(mesh).size();  // simplify() drops them (report: input)
    }
    if (job.triangles == 0) throw std::runtime_error("the asset has no triangles to simplify");
    // The size the asset is seen at: in world space, through its glTF nodes' transforms.
    job.diagonal = io::world_bounds(job.asset).diagonal();
    job.record["input"] = {{"triangles", job.triangles},
                           {"vertices", job.vertices},
                           {"diagonal", finite(job.diagonal)},
                           {"repeated_faces", job.repeated_faces},
                           {"bytes", asset_bytes(job.file)},
                           {"symmetry", symmetry_json(job.asset.meshes, job.cls->options.pending.symmetry_plane)}};
  }

  void lods(Job& job) {
    if (job.terrain) {
      for (terrain::Patch& p : job.terrain->patches) {
        if (p.lods[0].face_count() == 0) continue;
        auto chain = std::make_shared<MeshChain>();
        for (std::size_t k = 1; k < p.lods.size(); ++k)
          chain->push_back(MeshLod{.mesh = std::move(p.lods[k]), .error_bound_abs = 0, .budget = {}});
        job.chains.push_back(std::move(chain));
      }
      job.terrain.reset();
      return;
    }
    // Over the budget, the asset runs alone: its simplifications are fitted to the budget (tiled where needed).
    const std::optional<std::uint64_t> memory_limit =
        job.footprint > asset_budget_ ? std::optional(asset_budget_) : std::nullopt;
    std::uint64_t asset_bytes = 0;
    for (const Mesh& mesh : job.asset.meshes) asset_bytes += mesh_bytes(mesh);
    std::uint64_t chains_bytes = 0;  // the chains built so far
    for (const Mesh& mesh : job.asset.meshes) {
      if (mesh.triangle_count() == 0) {  // e.g. a glTF mesh of lines only: its LODs are itself
        auto chain = std::make_shared<MeshChain>();
        for (std::size_t k = 0; k < job.cls->lods.size(); ++k)
          chain->push_back(MeshLod{.mesh = mesh, .error_bound_abs = 0, .budget = {}});
        job.chains.push_back(std::move(chain));
        continue;
      }
      // The world diagonal in the mesh's own units: relative budgets are of the asset as the scene shows it.
      const double diagonal = job.diagonal / io::world_scale(job.asset, job.chains.size());
      Hasher key;
      key.bytes(mesh_content_hash(mesh)).bytes(job.cls->name).u64(job.triangles);
      key.u64(std::bit_cast<std::uint64_t>(diagonal));
      std::atomic<bool>* expire = job.path == options_.expire_in_simplify ? &job.expired : nullptr;
      const std::uint64_t held = asset_bytes - mesh_bytes(mesh) + chains_bytes;
      job.chains.push_back(chains_.get(key.hex(), [&] {
        return build_chain(mesh, *job.cls, job.triangles, diagonal, jobs_, job.stop_request(), memory_limit, held,
                           expire);
      }));
      for (const MeshLod& l : *job.chains.back()) chains_bytes += mesh_bytes(l.mesh);
    }
    if (job.cls->conservative.empty()) return;
    for (std::size_t m = 0; m < job.asset.meshes.size(); ++m) {
      const Mesh& mesh = job.asset.meshes[m];
      if (mesh.triangle_count() == 0) {
        MeshLod itself;  // e.g. a glTF mesh of lines only: its LODs are itself
        itself.mesh = mesh;
        job.conservative_built.emplace_back(job.cls->conservative.size(), itself);
        continue;
      }
      const double diagonal = job.diagonal / io::world_scale(job.asset, m);
      std::uint64_t held = asset_bytes - mesh_bytes(mesh) + chains_bytes;
      for (const std::vector<MeshLod>& built : job.conservative_built) {
        for (const MeshLod& l : built) held += mesh_bytes(l.mesh);
      }
      job.conservative_built.push_back(build_conservative(mesh, *job.cls, job.triangles, diagonal, jobs_,
                                                          job.stop_request(), memory_limit, held));
    }
  }

  void post_process(Job& job) {
    const bool optimize = config_.output.post_process;
    const std::size_t levels = job.cls->lods.size();
    job.levels.assign(levels, {});
    for (std::size_t k = 0; k < levels; ++k) {
      job.check_deadline();
      for (const auto& chain : job.chains) {
        const Mesh& lod = (*chain)[k].mesh;
        job.levels[k].push_back(optimize ? optimize_for_gpu(lod) : lod);
      }
    }
    job.conservative.assign(job.cls->conservative.size(), {});
    for (std::size_t c = 0; c < job.conservative.size(); ++c) {
      job.check_deadline();
      for (const std::vector<MeshLod>& built : job.conservative_built) {
        job.conservative[c].push_back(optimize ? optimize_for_gpu(built[c].mesh) : built[c].mesh);
      }
    }
    // LOD0 is written too (MSFT_lod files hold it; write_source_lod0 copies it), so it gets the same treatment.
    if (optimize) {
      for (const Mesh& mesh : job.asset.meshes) job.sources.push_back(optimize_for_gpu(mesh));
    } else {
      job.sources = job.asset.meshes;
    }
    // A level not at least 10% smaller than the one before is close to a copy of it: it shows that level's
    // meshes instead (MSFT_lod points its node there; files mode writes no file for it).
    auto triangles_of = [](const std::vector<Mesh>& meshes) {
      std::size_t n = 0;
      for (const Mesh& m : meshes) n += m.triangle_count();
      return n;
    };
    job.shows_previous.assign(levels, false);
    std::size_t before = triangles_of(job.sources);
    for (std::size_t k = 0; k < levels; ++k) {
      const std::size_t now = triangles_of(job.levels[k]);
      if (now > 0 && 10 * now > 9 * before) {
        job.levels[k] = k == 0 ? job.sources : job.levels[k - 1];
        job.shows_previous[k] = true;
      } else {
        before = now;
      }
    }
  }

  // The report's distances of a LOD from its source (both in world space), sampled by their size.
  // `reference` is the source prepared once per asset (`source_triangles` its triangle count).
  EvalResult evaluate_lod(Job& job, const EvalReference& reference, std::size_t source_triangles,
                          const Mesh& lod) const {
    const std::size_t larger = std::max(source_triangles, lod.triangle_count());
    EvalOptions eval;
    eval.samples = std::clamp(kEvalSamplesPerTriangle * larger, kEvalSamplesMin, kEvalSamplesMax);
    eval.threads = threads_for(larger, jobs_);
    eval.stop = job.stop_request();
    EvalResult e = evaluate(reference, lod, eval);
    if (e.stopped) throw TimedOut{};
    return e;
  }

  void measure(Job& job) {
    // Measured in world space (glTF node transforms applied), as the asset is seen and as its diagonal is.
    io::Asset placed = with_meshes(job.asset, job.sources);
    const Mesh source = io::world_surface(placed);
    const std::size_t source_triangles = source.triangle_count();
    // Every LOD is measured against the same source: its surface and BVH are built once.
    std::optional<EvalReference> reference;
    auto prepared = [&]() -> const EvalReference& {
      if (!reference) reference.emplace(source, threads_for(source_triangles, jobs_));
      return *reference;
    };
    Json lods = Json::array();
    double coverage_above = 1.0;
    job.coverage.clear();
    for (std::size_t k = 0; k < job.levels.size(); ++k) {
      job.check_deadline();
      const LodSpec& spec = job.cls->lods[k];
      std::size_t triangles = 0, vertices = 0;
      double bound = 0, seconds = 0;
      bool verified = true, met = true, certified = true;
      std::size_t undone = 0;
      std::set<std::string> stops;
      std::vector<std::string> floors;  // what held the meshes that missed, first seen first
      SeamStage seam_stage = SeamStage::strict;
      std::size_t memory_tiles = 0;
      for (std::size_t m = 0; m < job.levels[k].size(); ++m) {
        triangles += job.levels[k][m].triangle_count();
        vertices += job.levels[k][m].vertex_count();
        const MeshLod& built = (*job.chains[m])[k];
        bound = std::max(bound, built.error_bound_abs * io::world_scale(job.asset, m));
        seconds += built.seconds;
        note_memory(built, "LOD " + std::to_string(k + 1) + " of mesh " + std::to_string(m), memory_tiles,
                    job.record);
        if (job.asset.meshes[m].triangle_count() > 0) {
          verified = verified && built.budget.verified;
          met = met && built.budget.within;
          certified = certified && built.budget.certified;
          undone += built.budget.collapses_undone;
        }
        if (job.asset.meshes[m].triangle_count() > 0) stops.insert(stop_reason_name(built.stop));
        for (const std::string& f : built.floors) {
          if (std::find(floors.begin(), floors.end(), f) == floors.end()) floors.push_back(f);
        }
        seam_stage = std::max(seam_stage, built.seam_stage);
      }
      std::string stop;
      for (const std::string& s : stops) stop += (stop.empty() ? "" : ",") + s;
      const std::size_t previous = k == 0 ? job.triangles : lods.back()["triangles"].get<std::size_t>();

      // A terrain's ratio targets count the surface, not the skirts (which grow with the level's wall vertices).
      const std::size_t target_source = job.terrain_surface.empty() ? job.triangles : job.terrain_surface_total(0);
      const std::size_t target_triangles = job.terrain_surface.empty() ? triangles : job.terrain_surface_total(k + 1);

      placed.meshes = job.levels[k];
      const Mesh lod = io::world_surface(placed);
      const EvalResult e = evaluate_lod(job, prepared(), source_triangles, lod);
      const quad::QuadStats quads = quad::quad_stats(lod);

      // Where this LOD switches in (share of screen height): the config's own screen size, else where its
      // measured error covers lod_switch.error_px pixels; never above the previous LOD's (a valid MSFT_lod
      // series).
      double coverage =
          spec.target.kind == TargetKind::screen_size
              ? spec.target.screen.screen_coverage()
              : coverage_for_error(e.hausdorff_rel(), config_.lod_switch.error_px, config_.lod_switch.screen_height_px);
      coverage = std::clamp(coverage, 0.0, coverage_above);
      coverage_above = coverage;
      job.coverage.push_back(coverage);

      lods.push_back(
          {{"level", k + 1},
           {"from", spec.from == LodFrom::previous ? "previous" : "source"},
           {"target", target_json(spec.target)},
           {"target_triangles", target_triangles_json(spec.target, target_source)},
           {"triangles", triangles},
           {"vertices", vertices},
           {"ratio", double(triangles) / double(job.triangles)},
           {"error_bound_abs", finite(bound)},
           {"error_bound_rel", finite(job.diagonal > 0 ? bound / job.diagonal : 0.0)},
           // certified: an upper bound on the LOD's distance to the source; measured: met by
           // the budget's samples where the bound could not be refined; qem: a ranking only.
           {"error_bound_kind", verified ? (certified ? "certified" : "measured") : "qem"},
           {"budget", budget_json(spec.target, target_source, target_triangles, k == 0 ? job.triangles : previous, k,
                                  stops, verified && met, undone, job.shows_previous[k], floors)},
           {"seam_stage", seam_stage_name(seam_stage)},
           {"memory_tile_triangles", memory_tiles > 0 ? Json(memory_tiles) : Json(nullptr)},
           {"mean_rel", finite(e.mean_rel())},
           {"rms_rel", finite(e.rms_rel())},
           {"hausdorff_rel", finite(e.hausdorff_rel())},
           {"normal_deviation_mean_deg", finite(e.normal_deviation_mean_deg)},
           {"attributes", attribute_metrics(e, job.sources, job.levels[k], jobs_, job.stop_request())},
           {"quad_fraction", finite(quads.quad_fraction)},
           {"irregular_vertices", quads.irregular_vertices},
           {"stop_reason", stop},
           {"seconds", seconds},
           {"screen_coverage", coverage},
           {"shows_previous", job.shows_previous[k]}});
    }
    job.coverage.push_back(0.0);  // the coarsest LOD is never culled
    for (std::size_t k = 1; k < lods.size(); ++k) {
      if (lods[k]["triangles"].get<std::size_t>() > lods[k - 1]["triangles"].get<std::size_t>()) {
        job.record["warnings"].push_back("LOD " + std::to_string(k + 1) + " has more triangles than LOD " +
                                         std::to_string(k) + " (its targets mix kinds)");
        break;  // said once per asset
      }
    }
    job.record["lods"] = std::move(lods);
    if (!job.cls->conservative.empty()) {
      job.record["conservative_lods"] = conservative_records(job, source, prepared(), placed);
    }
  }

  // report.json "conservative_lods": per collision/occluder entry what it asked and what it got, measured against
  // the source in world space like the render LODs, plus the volume change where the source is closed.
  Json conservative_records(Job& job, const Mesh& source, const EvalReference& reference, io::Asset& placed) const {
    Json out = Json::array();
    const bool closed = summarize_topology(source, build_topology(source)).closed_manifold();
    const double source_volume = closed ? signed_volume(source) : 0.0;
    const bool in_gltf = is_gltf(job.asset.format) && config_.output.gltf_lods != GltfLods::files;
    for (std::size_t c = 0; c < job.cls->conservative.size(); ++c) {
      job.check_deadline();
      const ConservativeSpec& spec = job.cls->conservative[c];
      std::size_t triangles = 0, vertices = 0, undone = 0, refused = 0;
      double bound = 0, seconds = 0;
      bool verified = true, met = true, certified = true;
      std::set<std::string> stops;
      std::vector<std::string> floors;
      std::size_t memory_tiles = 0;
      for (std::size_t m = 0; m < job.conservative[c].size(); ++m) {
        triangles += job.conservative[c][m].triangle_count();
        vertices += job.conservative[c][m].vertex_count();
        if (job.asset.meshes[m].triangle_count() == 0) continue;
        const MeshLod& built = job.conservative_built[m][c];
        bound = std::max(bound, built.error_bound_abs * io::world_scale(job.asset, m));
        seconds += built.seconds;
        verified = verified && built.budget.verified;
        met = met && built.budget.within;
        certified = certified && built.budget.certified;
        undone += built.budget.collapses_undone;
        refused += built.conservative_refused;
        note_memory(built, std::string(conservative_kind_name(spec.kind)) + " LOD of mesh " + std::to_string(m),
                    memory_tiles, job.record);
        stops.insert(stop_reason_name(built.stop));
        for (const std::string& f : built.floors) {
          if (std::find(floors.begin(), floors.end(), f) == floors.end()) floors.push_back(f);
        }
      }
      std::string stop;
      for (const std::string& s : stops) stop += (stop.empty() ? "" : ",") + s;
      placed.meshes = job.conservative[c];
      const Mesh lod = io::world_surface(placed);
      const EvalResult e = evaluate_lod(job, reference, source.triangle_count(), lod);
      // Volume change in per cent of the source's (bounding LODs grow, occluders shrink); null for an open source.
      const Json volume_change = closed && source_volume > 0
                                     ? Json(finite(100.0 * (signed_volume(lod) / source_volume - 1.0)))
                                     : Json(nullptr);

      const bool collision = spec.kind == ConservativeKind::collision;
      const Json target = spec.target ? target_json(*spec.target)
                                      : Json{{"kind", "max_volume_growth"}, {"value", spec.max_volume_growth_pct}};
      const Json target_triangles = spec.target ? target_triangles_json(*spec.target, job.triangles) : Json(nullptr);
      Json reasons = Json::array();
      std::string why_stopped;
      for (const std::string& s : stops) {
        if (s != "target_reached") why_stopped += (why_stopped.empty() ? "" : ", ") + s;
      }
      if (spec.target && spec.target->kind != TargetKind::ratio && spec.target->kind != TargetKind::triangles) {
        if (!(verified && met)) reasons.push_back("error budget not met by measurement");
      } else if (target_triangles.is_number() &&
                 static_cast<double>(triangles) > std::ceil(1.02 * target_triangles.get<double>())) {
        reasons.push_back("target not reached: " + std::to_string(triangles) + " triangles for " +
                          std::to_string(target_triangles.get<std::size_t>()) +
                          (why_stopped.empty() ? std::string() : " (stopped: " + why_stopped + ")") +
                          (floors.empty() ? std::string() : "; floor: " + joined(floors)));
      }
      // The simplifier sums the volume exactly as it goes; the slack covers the written floats.
      if (collision && spec.max_volume_growth_pct >= 0 && volume_change.is_number() &&
          volume_change.get<double>() > spec.max_volume_growth_pct + 1e-6) {
        char text[96];
        std::snprintf(text, sizeof text, "volume grew by %.3f%% of the source's, over its budget of %g%%",
                      volume_change.get<double>(), spec.max_volume_growth_pct);
        reasons.push_back(text);
      }
      Json budget{{"status", reasons.empty() ? "met" : "missed"}, {"reasons", std::move(reasons)}};
      if (spec.target && target_triangles.is_null()) budget["collapses_backed_off"] = undone;

      const std::string kind = conservative_kind_name(spec.kind);
      out.push_back({{"kind", kind},
                     {"mode", collision ? "bounding" : "occluder"},
                     {"target", target},
                     {"target_triangles", target_triangles},
                     {"max_volume_growth_pct",
                      spec.max_volume_growth_pct >= 0 ? Json(spec.max_volume_growth_pct) : Json(nullptr)},
                     {"triangles", triangles},
                     {"vertices", vertices},
                     {"ratio", double(triangles) / double(job.triangles)},
                     {"error_bound_abs", finite(bound)},
                     {"error_bound_rel", finite(job.diagonal > 0 ? bound / job.diagonal : 0.0)},
                     {"error_bound_kind", verified ? (certified ? "certified" : "measured") : "qem"},
                     {"budget", std::move(budget)},
                     {"mean_rel", finite(e.mean_rel())},
                     {"rms_rel", finite(e.rms_rel())},
                     {"hausdorff_rel", finite(e.hausdorff_rel())},
                     {"volume_change_pct", volume_change},
                     {"collapses_refused", refused},
                     {"memory_tile_triangles", memory_tiles > 0 ? Json(memory_tiles) : Json(nullptr)},
                     {"stop_reason", stop},
                     {"seconds", seconds},
                     {"outputs", Json::array()},
                     {"gltf_node_suffix", in_gltf ? Json("_" + kind) : Json(nullptr)}});
    }
    return out;
  }

  void write(Job& job) {
    const fs::path staging = cache_.staging_for(job.path);
    try {
      write_outputs(job, staging);
      job.check_deadline();  // last moment to give up: once published, the asset is done
      job.record["output_bytes"] = tree_bytes(staging);
      job.record["outputs"] = cache_.publish(staging, fs::path(job.path).parent_path());
      if (job.record.contains("conservative_lods")) {
        for (Json& entry : job.record["conservative_lods"]) {
          const ConservativeKind kind =
              entry["kind"] == "collision" ? ConservativeKind::collision : ConservativeKind::occluder;
          const std::string stem =
              fs::path(conservative_file_name(fs::path(job.path).filename(), kind)).stem().string();
          for (const Json& o : job.record["outputs"]) {
            if (fs::path(o.get<std::string>()).stem() == stem) entry["outputs"].push_back(o);
          }
        }
      }
    } catch (...) {
      std::error_code ec;
      fs::remove_all(staging, ec);
      throw;
    }
    job.record["seconds"] = work_seconds(job.stages);  // the write itself is added when the asset is reported
    cache_.store(job.path, job.key, job.record["outputs"].get<std::vector<std::string>>(), job.record);
    job.processed_triangles = job.triangles;
  }

  bool wants_pictures(const Job& job) const {
    if (!options_.write_report) return false;  // pictures go beside the report
    switch (config_.report.pictures) {
      case ReportPictures::on:
        return true;
      case ReportPictures::off:
        return false;
      case ReportPictures::automatic: {
        std::size_t rendered = job.triangles;
        for (std::size_t k = 0; k < job.levels.size(); ++k) {
          for (const Mesh& m : job.levels[k]) rendered += job.shows_previous[k] ? 0 : m.triangle_count();
        }
        return pictures_pay(job.triangles, rendered, job.levels.size() + 1);
      }
    }
    return false;
  }

  // The source and each level in world space, all in the source's frame so they share one scale. Never throws:
  // a picture that cannot be drawn costs the asset its pictures (and a warning), nothing else.
  static void pictures(Job& job) {
    try {
      io::Asset placed = with_meshes(job.asset, job.sources);
      const Mesh source = io::world_surface(placed);
      // A terrain is seen from above, each patch coloured by its share of a full patch's triangles.
      const bool terrain = !job.terrain_surface.empty();
      const io::PictureFrame frame = io::frame_mesh(source, *io::find_picture_view(terrain ? "top" : "iso"));
      auto colours = [&](std::size_t level, const std::vector<Mesh>& meshes) {
        std::vector<std::array<std::uint8_t, 3>> out;
        if (!terrain) return out;
        for (std::size_t m = 0; m < meshes.size(); ++m) {
          out.insert(out.end(), meshes[m].triangle_count(),
                     terrain::patch_colour(job.terrain_surface[level][m], job.cls->terrain->patch_cells));
        }
        return out;
      };
      job.picture_png.push_back(
          io::encode_png(io::render_picture(source, frame, kPictureSize, colours(0, job.sources))));
      for (std::size_t k = 0; k < job.levels.size(); ++k) {
        if (job.deadline && Clock::now() > *job.deadline) {  // the asset fails anyway
          job.picture_png.clear();
          return;
        }
        if (job.shows_previous[k]) {  // the same meshes as the level before
          job.picture_png.push_back(std::string(job.picture_png.back()));
          continue;
        }
        placed.meshes = job.levels[k];
        job.picture_png.push_back(io::encode_png(
            io::render_picture(io::world_surface(placed), frame, kPictureSize, colours(k + 1, job.levels[k]))));
      }
    } catch (const std::exception& e) {
      job.picture_png.clear();
      job.picture_error = e.what();
    } catch (...) {
      job.picture_png.clear();
      job.picture_error = "unknown error";
    }
  }

  // Once both branches are done: an asset rebuilt this run gets its new pictures published (each file written
  // to a temporary name and renamed) and listed in its record, or, without any, loses the old ones, which would
  // show LODs it no longer has. A cache hit lists the pictures an earlier run drew for the same outputs; a failed
  // asset keeps those of its last good run, as it keeps its outputs. Never fails the asset.
  void finish_pictures(Job& job) const {
    const auto t0 = Clock::now();
    const bool ok = job.record["status"] == "ok", hit = job.record["cache_hit"] == true;
    const fs::path folder = options_.output_dir / kPictureFolder / fs::path(job.path);
    std::vector<std::string> names;
    std::error_code ec;
    if (!ok || !options_.write_report) {
      // nothing to change
    } else if (hit) {
      const std::size_t n = job.record["lods"].size() + 1;
      for (std::size_t k = 0; k < n && config_.report.pictures != ReportPictures::off; ++k) {
        names.push_back(picture_file_name(job.path, k));
        if (!fs::is_regular_file(options_.output_dir / names.back(), ec)) {
          names.clear();
          break;
        }
      }
    } else if (!job.picture_png.empty()) {
      try {
        for (std::size_t k = 0; k < job.picture_png.size(); ++k) {
          names.push_back(picture_file_name(job.path, k));
          fs::create_directories(folder, ec);
          io::write_file_atomic(options_.output_dir / names.back(), job.picture_png[k], io::Durability::none);
        }
        // Levels the asset no longer has.
        for (std::size_t k = job.picture_png.size();; ++k) {
          if (!fs::remove(options_.output_dir / picture_file_name(job.path, k), ec)) break;
        }
      } catch (const std::exception& e) {
        names.clear();
        fs::remove_all(folder, ec);
        job.record["warnings"].push_back(std::string("no pictures: ") + e.what());
      }
    } else {
      fs::remove_all(folder, ec);
      if (!job.picture_error.empty()) job.record["warnings"].push_back("no pictures: " + job.picture_error);
    }
    if (!names.empty()) job.record["pictures"] = names;
    job.picture_png.clear();
    job.picture_png.shrink_to_fit();
    job.stages.pictures += seconds_since(t0);
  }

 private:
  void write_outputs(Job& job, const fs::path& staging) {
    // A height map's LODs are glTF: "hills.r16" → "hills.glb".
    const fs::path name =
        job.cls->terrain ? fs::path(job.path).filename().replace_extension(".glb") : fs::path(job.path).filename();
    const io::Format format = job.asset.format;
    const GltfLods mode = config_.output.gltf_lods;
    if (is_gltf(format) && mode != GltfLods::files) {
      io::LodChain chain{
          .levels = job.levels, .screen_coverage = job.coverage, .shows_previous = job.shows_previous, .separate = {}};
      for (std::size_t c = 0; c < job.conservative.size(); ++c) {
        chain.separate.push_back({.suffix = std::string("_") + conservative_kind_name(job.cls->conservative[c].kind),
                                  .meshes = job.conservative[c]});
      }
      io::save_gltf_lods(with_meshes(job.asset, job.sources), chain, staging / name);
    }
    if (!is_gltf(format) || mode != GltfLods::msft_lod) {
      for (std::size_t k = 0; k < job.levels.size(); ++k) {
        if (job.shows_previous[k]) continue;  // a near-copy of the level before: no duplicate file
        io::save_asset(with_meshes(job.asset, job.levels[k]), staging / lod_file_name(name, k + 1));
      }
      for (std::size_t c = 0; c < job.conservative.size(); ++c) {
        io::save_asset(with_meshes(job.asset, job.conservative[c]),
                       staging / conservative_file_name(name, job.cls->conservative[c].kind));
      }
    }
    if (config_.output.write_source_lod0) {
      io::save_asset(with_meshes(job.asset, job.sources), staging / lod_file_name(name, 0));
    }
    if (format == io::Format::obj) copy_mtllibs(job, staging);
  }

  // OBJ material libraries go next to the LODs that name them (their textures are not followed).
  static void copy_mtllibs(const Job& job, const fs::path& staging) {
    const fs::path folder = job.file.parent_path();
    for (const std::string& line : job.asset.obj_mtllibs) {
      try {
        const fs::path source = io::resolve_inside(job.file, folder, line);
        std::error_code ec;
        if (!fs::is_regular_file(source, ec)) continue;
        const fs::path dest = staging / fs::relative(source, folder);
        fs::create_directories(dest.parent_path(), ec);
        io::write_file_atomic(dest, io::read_file(source));
      } catch (const io::IoError&) {
        // A library outside the asset's folder (or several names on one line) is not copied; the LOD files
        // still name it as the source did.
      }
    }
  }

  const BatchConfig& config_;
  const RunOptions& options_;
  const Cache& cache_;
  unsigned jobs_;
  std::uint64_t asset_budget_;
  ChainTable chains_;
  std::map<const AssetClass*, Json> class_json_;
};

void fail(Job& job, const std::string& error) {
  job.record["status"] = "failed";
  job.record["error"] = error.empty() ? "unknown error" : error;
  job.record["outputs"] = Json::array();
  job.record["lods"] = Json::array();
  job.record.erase("conservative_lods");
  job.finished = true;
}

// A timeout beyond a year is no limit (and would overflow the clock's representation).
constexpr double kMaxTimeoutSeconds = 365.0 * 24 * 3600;

std::string timeout_message(const char* stage, double timeout_s) {
  char seconds[32];
  std::snprintf(seconds, sizeof seconds, "%g", timeout_s);
  return std::string("timed out in the ") + stage + " stage (asset timeout " + seconds + " s)";
}

// Wraps a stage: skips finished jobs, times the stage, and turns any exception into the asset's failure. With an
// asset timeout, the first stage sets the deadline; later stages check it on entry, and every stage on exit
// unless it finished the asset (a cache hit, or the write stage, which gives up only before it publishes: a
// published asset is complete). The stages also check it inside their long loops.
template <class F>
auto stage(F body, double StageSeconds::*field, const char* name, double timeout_s, const RunOptions& options) {
  return [body, field, name, timeout_s, &options](JobPtr job) -> JobPtr {
    if (job->finished) return job;
    const auto t0 = Clock::now();
    const bool first = timeout_s > 0 && timeout_s < kMaxTimeoutSeconds && !job->deadline;
    if (first) {
      job->deadline = t0 + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(timeout_s));
    }
    try {
      if (options.on_stage_start) options.on_stage_start(job->path, name);
      if (job->deadline && options.expire_on_stage && options.expire_on_stage(job->path, name)) {
        job->expired_at_stage = true;
      }
      if (!first) job->check_deadline();
      body(*job);
      if (!job->finished && field != &StageSeconds::write) job->check_deadline();
    } catch (const TimedOut&) {
      fail(*job, timeout_message(name, timeout_s));
    } catch (const io::IoError& e) {
      // The record and the failure list name the asset already; its path is not repeated in the message.
      fail(*job, e.file() == job->file ? e.problem() : e.what());
    } catch (const std::exception& e) {
      fail(*job, e.what());
    } catch (...) {
      fail(*job, "unknown error");
    }
    job->stages.*field += seconds_since(t0);
    return job;
  };
}

bool supported(const fs::path& p) {
  try {
    io::format_from_path(p);
    return true;
  } catch (const io::IoError&) {
    return false;
  }
}

// Files that belong to assets without being assets (glTF buffers and textures, OBJ materials) or to the file
// system (hidden files): not worth a warning about unsupported files.
bool companion_file(const fs::path& p) {
  const std::string name = p.filename().string();
  if (!name.empty() && name[0] == '.') return true;
  if (p.extension() == ".json" && io::is_heightmap_path(p.stem())) return true;  // a height map's sidecar
  const std::string ext = io::lower_extension(p);
  for (const char* e : {".bin", ".mtl", ".png", ".jpg", ".jpeg", ".ktx2", ".webp", ".dds", ".tga", ".basis"}) {
    if (ext == e) return true;
  }
  return false;
}

// Bytes of the asset's mesh data on disk: the file, plus for a .gltf the buffers it declares (its JSON is small;
// the geometry is in the .bin files). Read only from the JSON's byteLength fields, so the scan stays cheap.
std::uint64_t asset_bytes(const fs::path& file) {
  std::error_code ec;
  std::uint64_t bytes = fs::file_size(file, ec);
  if (ec) return 0;
  if (io::is_heightmap_path(file) || io::format_from_path(file) != io::Format::gltf) return bytes;
  try {
    const Json doc = Json::parse(io::read_file(file), nullptr, false);
    if (doc.is_object() && doc.contains("buffers") && doc["buffers"].is_array()) {
      for (const Json& b : doc["buffers"]) {
        if (b.is_object() && b.contains("byteLength") && b["byteLength"].is_number_unsigned()) {
          bytes += b["byteLength"].get<std::uint64_t>();
        }
      }
    }
  } catch (const io::IoError&) {
    // unreadable: the load stage reports it
  }
  return bytes;
}

void remove_report_leftovers(const fs::path& output_dir, const std::vector<std::string>& names) {
  std::error_code ec;
  std::vector<fs::path> stale;
  for (auto it = fs::directory_iterator(output_dir, ec); !ec && it != fs::directory_iterator(); it.increment(ec)) {
    const std::string file = it->path().filename().string();
    for (const std::string& n : names) {
      if (file.rfind(n + ".tmp-", 0) == 0) stale.push_back(it->path());
    }
  }
  for (const fs::path& p : stale) fs::remove(p, ec);
}

// Peak memory per byte of file, by format: ~1150 bytes per triangle (measured, see runner.hpp above
// kFootprintOverhead) over the densest encoding of a triangle in the format.
std::uint64_t footprint_per_file_byte(io::Format format) {
  switch (format) {
    case io::Format::gltf:
    case io::Format::glb:
      return 96;  // 12 bytes per triangle
    case io::Format::ply:
      return 60;  // binary: 12 bytes per vertex (half a vertex per triangle) + 13 per face
    case io::Format::stl:
      return 24;  // binary: 50 bytes per triangle
    default:
      return 36;  // OBJ, OFF: ~32 characters per triangle at the shortest useful precision
  }
}

}  // namespace

std::uint64_t estimate_footprint(const fs::path& file) {
  // A height map: about 300 bytes of meshes (every level, the copies for output) per byte of samples.
  if (io::is_heightmap_path(file)) return asset_bytes(file) * 300 + kFootprintOverhead;
  io::Format format;
  try {
    format = io::format_from_path(file);
  } catch (const io::IoError&) {
    return kFootprintOverhead;
  }
  return asset_bytes(file) * footprint_per_file_byte(format) + kFootprintOverhead;
}

std::uint64_t default_memory_limit() {
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGESIZE);
  if (pages <= 0 || page <= 0) return 4ull << 30;
  return static_cast<std::uint64_t>(pages) * static_cast<std::uint64_t>(page) / 2;
}

std::uint64_t parse_byte_size(std::string_view text) {
  std::string s(text);
  while (!s.empty() && (s.back() == 'B' || s.back() == 'b' || s.back() == 'i')) s.pop_back();  // "4GB", "4GiB"
  std::uint64_t unit = 1;
  if (!s.empty()) {
    switch (s.back()) {
      case 'k':
      case 'K':
        unit = 1ull << 10;
        break;
      case 'm':
      case 'M':
        unit = 1ull << 20;
        break;
      case 'g':
      case 'G':
        unit = 1ull << 30;
        break;
      case 't':
      case 'T':
        unit = 1ull << 40;
        break;
      default:
        break;
    }
    if (unit != 1) s.pop_back();
  }
  std::size_t used = 0;
  double value = -1;
  try {
    value = std::stod(s, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (s.empty() || used != s.size() || !(value > 0) || !std::isfinite(value) || value * double(unit) > 1e18) {
    throw std::invalid_argument("'" + std::string(text) + "' is not a byte size (e.g. 4G, 512M, 1000000)");
  }
  return static_cast<std::uint64_t>(value * double(unit));
}

std::string picture_file_name(const std::string& relative_path, std::size_t level) {
  return std::string(kPictureFolder) + "/" + relative_path + "/lod" + std::to_string(level) + ".png";
}

// Costs in the time an asset's processing (load, simplify, evaluate, write) spends per input triangle, measured
// with `lodforge run` over the corpus (docs/report.md): processing costs about kWorkFixed + 1 per triangle; a
// picture about kPictureFixed (clearing, encoding and writing the PNG) plus kPicturePerTriangle per triangle
// drawn. Rounded up, so that the rule errs towards no pictures.
constexpr double kWorkFixed = 400, kPictureFixed = 100, kPicturePerTriangle = 0.01, kPictureShare = 0.05;

bool pictures_pay(std::size_t input_triangles, std::size_t rendered_triangles, std::size_t pictures) {
  const double cost = kPictureFixed * double(pictures) + kPicturePerTriangle * double(rendered_triangles);
  return cost <= kPictureShare * (kWorkFixed + double(input_triangles));
}

std::string lod_file_name(const fs::path& relative_path, std::size_t level) {
  return relative_path.stem().string() + "_LOD" + std::to_string(level) + relative_path.extension().string();
}

std::string conservative_file_name(const fs::path& relative_path, ConservativeKind kind) {
  return relative_path.stem().string() + "_" + conservative_kind_name(kind) + relative_path.extension().string();
}

LibraryScan scan_library(const fs::path& input_dir) {
  std::error_code ec;
  if (!fs::is_directory(input_dir, ec)) throw io::IoError(input_dir, "is not a folder");
  LibraryScan out;
  auto skip = [&out](const fs::path& entry, const std::string& why) {
    out.skipped.push_back(entry.string() + ": skipped: " + why);
  };
  const auto options = fs::directory_options::skip_permission_denied;
  for (auto it = fs::recursive_directory_iterator(input_dir, options, ec);
       !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    // Status through symbolic links; the error_code form, as a link loop or an unreadable entry must not end
    // the scan.
    std::error_code status_ec;
    const fs::file_type type = it->status(status_ec).type();
    if (type == fs::file_type::not_found) {
      if (supported(it->path())) skip(it->path(), "broken symbolic link");
      continue;
    }
    if (status_ec) {
      skip(it->path(),
           status_ec == std::errc::too_many_symbolic_link_levels ? "symbolic link loop" : status_ec.message());
      continue;
    }
    if (type == fs::file_type::directory) {
      // The cache and outputs of a run into a folder inside the library are not assets.
      if (it->path().filename() == kCacheFolder) {
        it.disable_recursion_pending();
        continue;
      }
      // The iterator passes over a folder it cannot open without a word (skip_permission_denied); linked
      // folders are not entered at all.
      std::error_code open_ec;
      if (it->is_symlink(open_ec)) continue;
      const fs::directory_iterator probe(it->path(), open_ec);
      if (open_ec) skip(it->path(), "cannot open the folder: " + open_ec.message());
      continue;
    }
    // Lexically: fs::relative would resolve a linked file to its target's path (a duplicate, or "../x.obj",
    // whose LODs would be written outside the output folder).
    if (type == fs::file_type::regular) {
      const std::string rel = it->path().lexically_relative(input_dir).generic_string();
      if (supported(it->path()))
        out.assets.push_back(rel);
      else if (io::is_heightmap_path(it->path()))
        out.heightmaps.push_back(rel);
      else if (!companion_file(it->path()))
        out.unsupported.push_back(rel);
    }
  }
  if (ec) throw io::IoError(input_dir, "cannot list the folder: " + ec.message());
  std::sort(out.assets.begin(), out.assets.end());
  std::sort(out.skipped.begin(), out.skipped.end());
  std::sort(out.unsupported.begin(), out.unsupported.end());
  std::sort(out.heightmaps.begin(), out.heightmaps.end());
  return out;
}

namespace {

// The assets a run processes: the library's supported files less those of an output folder inside it, cut to
// the shard. Throws io::IoError for an unreadable library or one without a single asset file.
struct Selection {
  LibraryScan scan;
  std::vector<std::string> paths;
};

Selection select_assets(const BatchConfig& config, const RunOptions& options) {
  Selection sel{scan_library(options.input_dir), {}};
  LibraryScan& scan = sel.scan;
  // A height map is an asset only where a terrain class takes it; other PNGs are textures, other .r16 files
  // unsupported.
  for (std::string& h : scan.heightmaps) {
    const AssetClass* cls = match_class(config, h);
    if (cls != nullptr && cls->terrain) {
      scan.assets.push_back(std::move(h));
    } else if (!companion_file(options.input_dir / h)) {
      scan.unsupported.push_back(std::move(h));
    }
  }
  scan.heightmaps.clear();
  std::sort(scan.assets.begin(), scan.assets.end());
  std::sort(scan.unsupported.begin(), scan.unsupported.end());
  std::error_code ec;
  // An output folder inside the library is not part of it (its LODs would be assets of the next run).
  std::string output_prefix;
  {
    const fs::path rel =
        fs::weakly_canonical(options.output_dir, ec).lexically_relative(fs::weakly_canonical(options.input_dir, ec));
    if (rel == ".") throw io::IoError(options.output_dir, "the output folder must not be the library folder");
    if (!rel.empty() && *rel.begin() != "..") output_prefix = rel.generic_string() + "/";
  }
  auto in_output = [&output_prefix](const std::string& p) {
    return !output_prefix.empty() && p.rfind(output_prefix, 0) == 0;
  };
  std::erase_if(scan.unsupported, in_output);
  if (std::all_of(scan.assets.begin(), scan.assets.end(), in_output)) {
    throw io::IoError(options.input_dir,
                      "the library holds no asset files (.gltf .glb .obj .ply .off .stl, or height maps a "
                      "terrain class takes)" +
                          (scan.unsupported.empty()
                               ? std::string()
                               : ", only " + std::to_string(scan.unsupported.size()) + " file(s) of other types"));
  }
  for (const std::string& p : scan.assets) {
    if (in_output(p)) continue;
    if (!options.shard || in_shard(*options.shard, p)) sel.paths.push_back(p);
  }
  return sel;
}

// The saved terrain builds (load_terrain) of maps the library no longer holds, and the temporary files of writes
// that did not finish. Every shard scans the whole library, so no shard removes another's maps.
void prune_terrain_saves(const fs::path& output_dir, const std::vector<std::string>& library) {
  const fs::path folder = output_dir / kCacheFolder / "terrain";
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) return;
  std::set<std::string> kept;
  for (const std::string& p : library) kept.insert(Hasher().bytes(p).hex() + ".bin");
  std::vector<fs::path> stale;
  for (auto it = fs::directory_iterator(folder, ec); !ec && it != fs::directory_iterator(); it.increment(ec)) {
    if (!kept.contains(it->path().filename().string())) stale.push_back(it->path());
  }
  for (const fs::path& f : stale) fs::remove(f, ec);
}

std::string describe_target(const LodTarget& t) {
  const Json j = target_json(t);
  char value[32];
  std::snprintf(value, sizeof value, "%g", j["value"].get<double>());
  std::string out = j["kind"].get<std::string>() + " " + value;
  if (t.kind == TargetKind::max_error_abs) out += " (absolute)";
  return out;
}

// Files an output folder holds that a run writes: meshes, their buffers, materials and textures. Nothing else
// there is ever judged stale, so pointing --output at a folder of other files cannot lose them.
bool output_like(const fs::path& p) {
  const std::string ext = io::lower_extension(p);
  for (const char* e :
       {".gltf", ".glb", ".bin", ".obj", ".mtl", ".ply", ".off", ".stl", ".png", ".jpg", ".jpeg", ".ktx2", ".webp"}) {
    if (ext == e) return true;
  }
  return false;
}

// Output files of earlier runs that this run's assets no longer produce (sorted, '/'-separated, relative to the
// output folder). Assets that did not finish (failed, not started) keep what their last good run wrote.
std::vector<std::string> stale_outputs(const fs::path& output_dir, const fs::path& input_dir, const Cache& cache,
                                       const std::vector<std::string>& paths, const std::vector<Json>& records) {
  std::set<std::string> produced;
  for (std::size_t i = 0; i < records.size(); ++i) {
    const Json& r = records[i];
    if (r["status"] == "ok") {
      for (const Json& o : r["outputs"]) produced.insert(o.get<std::string>());
    } else if (r["status"] != "skipped") {
      for (std::string& o : cache.listed_outputs(paths[i])) produced.insert(std::move(o));
    }
  }
  const std::set<std::string> library(paths.begin(), paths.end());
  const std::string pictures = std::string(kPictureFolder) + "/";
  std::vector<std::string> stale;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(output_dir, ec); !ec && it != fs::recursive_directory_iterator();
       it.increment(ec)) {
    std::error_code type_ec;
    if (it->is_directory(type_ec)) {
      // A library inside the output folder holds the inputs, never outputs. Nor does the cache.
      if (it->path().filename() == kCacheFolder || fs::equivalent(it->path(), input_dir, type_ec)) {
        it.disable_recursion_pending();
      }
      continue;
    }
    if (!it->is_regular_file(type_ec) || !output_like(it->path())) continue;
    const std::string rel = it->path().lexically_relative(output_dir).generic_string();
    if (produced.count(rel)) continue;
    if (rel.starts_with(pictures)) {
      // The report's pictures (report_files/<asset>/lodK.png) stay while their asset is in the library, whatever
      // its last run did: they are its last good run's. Other files there are never judged.
      const fs::path picture(rel.substr(pictures.size()));
      const std::string name = picture.filename().string();
      const bool lod_picture =
          name.size() > 7 && name.starts_with("lod") && name.ends_with(".png") &&
          std::all_of(name.begin() + 3, name.end() - 4, [](char c) { return c >= '0' && c <= '9'; });
      if (lod_picture && !library.count(picture.parent_path().generic_string())) stale.push_back(rel);
      continue;
    }
    stale.push_back(rel);
  }
  std::sort(stale.begin(), stale.end());
  return stale;
}

// Removes the files and then the folders they leave empty, up to (not including) the output folder.
void remove_outputs(const fs::path& output_dir, const std::vector<std::string>& files) {
  std::error_code ec;
  for (const std::string& f : files) {
    fs::remove(output_dir / f, ec);
    for (fs::path dir = (output_dir / f).parent_path();
         dir != output_dir && dir.native().size() > output_dir.native().size(); dir = dir.parent_path()) {
      if (!fs::is_empty(dir, ec) || ec || !fs::remove(dir, ec)) break;
    }
  }
}

}  // namespace

Plan plan_batch(const BatchConfig& config, const RunOptions& options) {
  Selection sel = select_assets(config, options);
  const std::string tag =
      options.shard ? std::to_string(options.shard->index) + "-of-" + std::to_string(options.shard->count) : "0-of-1";
  const Cache cache(options.output_dir, tag, /*read_only=*/true);
  std::map<const AssetClass*, Json> class_json;
  for (const AssetClass& cls : config.classes) class_json[&cls] = effective_class_json(config, cls);

  Plan plan;
  plan.warnings = std::move(sel.scan.skipped);
  plan.unsupported = std::move(sel.scan.unsupported);
  plan.assets.resize(sel.paths.size());
  const unsigned jobs = options.jobs == 0 ? static_cast<unsigned>(tbb::info::default_concurrency()) : options.jobs;
  tbb::task_arena arena(static_cast<int>(jobs));
  arena.execute([&] {
    tbb::parallel_for(std::size_t{0}, sel.paths.size(), [&](std::size_t i) {
      PlannedAsset& a = plan.assets[i];
      a.path = sel.paths[i];
      const AssetClass* cls = match_class(config, a.path);
      if (!cls) {
        a.reason = unmatched_reason(config, a.path);
        return;
      }
      a.class_name = cls->name;
      for (const LodSpec& l : cls->lods) a.lods.push_back(describe_target(l.target));
      for (const ConservativeSpec& c : cls->conservative) {
        std::string what = std::string(conservative_kind_name(c.kind)) + " " +
                           (c.target ? describe_target(*c.target) : std::string("max_volume_growth"));
        if (c.max_volume_growth_pct >= 0 && c.target) what += ", max_volume_growth";
        if (c.max_volume_growth_pct >= 0) {
          char pct[32];
          std::snprintf(pct, sizeof pct, " %g%%", c.max_volume_growth_pct);
          what += pct;
        }
        a.separate.push_back(what);
      }
      if (options.force) {
        a.rebuild = true;
        a.reason = "--force";
        return;
      }
      try {
        const std::string key =
            cache_key(input_fingerprint(options.input_dir / a.path), class_json.at(cls), kAlgorithmVersion);
        a.reason = cache.why_stale(a.path, key);
      } catch (const io::IoError& e) {
        a.reason = "cannot be read: " + (e.file() == options.input_dir / a.path ? e.problem() : std::string(e.what()));
      }
      a.rebuild = !a.reason.empty();
    });
  });
  return plan;
}

RunResult run_batch(const BatchConfig& config, const RunOptions& options) {
  const auto t0 = Clock::now();
  const int cores = tbb::info::default_concurrency();
  const unsigned jobs = options.jobs == 0 ? static_cast<unsigned>(cores) : options.jobs;
  const std::uint64_t memory_limit = options.memory_limit_bytes ? options.memory_limit_bytes : default_memory_limit();
  const std::string tag =
      options.shard ? std::to_string(options.shard->index) + "-of-" + std::to_string(options.shard->count) : "0-of-1";
  const std::string report_stem = options.shard ? "report.shard-" + tag : "report";
  const std::string manifest_stem = options.shard ? "lods.shard-" + tag : "lods";

  // Scan (sorted), shard, classify.
  Selection sel = select_assets(config, options);
  LibraryScan& scan = sel.scan;
  const std::vector<std::string>& paths = sel.paths;
  std::error_code ec;
  fs::create_directories(options.output_dir, ec);
  if (ec) throw io::IoError(options.output_dir, "cannot create the output folder: " + ec.message());
  const Cache cache(options.output_dir, tag);

  cache.remove_leftovers(paths);
  prune_terrain_saves(options.output_dir, scan.assets);
  remove_report_leftovers(options.output_dir, {report_stem + ".json", report_stem + ".html", manifest_stem + ".json"});

  std::vector<Json> records(paths.size());
  std::vector<Pending> pending;
  for (std::size_t i = 0; i < paths.size(); ++i) {
    const AssetClass* cls = match_class(config, paths[i]);
    if (!cls) {
      records[i] = base_record(paths[i], nullptr);
      records[i]["status"] = "skipped";
      records[i]["error"] = unmatched_reason(config, paths[i]);
      continue;
    }
    pending.push_back({i, paths[i], cls, estimate_footprint(options.input_dir / paths[i])});
  }

  RunResult result;
  result.warnings = std::move(scan.skipped);
  result.unsupported = std::move(scan.unsupported);
  // One asset in flight per thread. Extra ones would wait as spawned tasks, and TBB runs the newest task
  // first, so they would sit (holding their memory budget) until the end of the run.
  // The assets' budget is the limit less what the process holds already (code, libraries, the library's path
  // list) and less the duplicate-chain cache, which lives outside any one asset.
  const std::uint64_t chain_cache = memory_limit / 8;
  const std::uint64_t held = resident_bytes() + chain_cache;
  const std::uint64_t budget = memory_limit > held ? memory_limit - held : 0;
  Admission admission(std::move(pending), budget, memory_limit, jobs, options.cancel, options.stop_after);
  std::size_t done = static_cast<std::size_t>(
      std::count_if(records.begin(), records.end(), [](const Json& r) { return !r.is_null(); }));
  std::uint64_t triangles_done = 0;

  // More threads than cores only when asked for: TBB otherwise caps an arena at the core count.
  std::optional<tbb::global_control> oversubscribe;
  if (jobs > static_cast<unsigned>(cores)) {
    oversubscribe.emplace(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(jobs));
  }
  tbb::task_arena arena(static_cast<int>(jobs));
  Pipeline pipeline(config, options, cache, jobs, chain_cache, budget);
  arena.execute([&] {
    namespace flow = tbb::flow;
    flow::graph g;
    using Node = flow::function_node<JobPtr, JobPtr>;
    const double timeout_s = config.limits.asset_timeout_s;
    auto make = [&](auto member, double StageSeconds::*field, const char* name) {
      return std::make_unique<Node>(
          g, flow::unlimited,
          stage([&pipeline, member](Job& j) { (pipeline.*member)(j); }, field, name, timeout_s, options));
    };
    // The names are those of the timeout message ("timed out in the simplify stage").
    auto fingerprint = make(&Pipeline::fingerprint, &StageSeconds::fingerprint, "fingerprint");
    auto load = make(&Pipeline::load, &StageSeconds::load, "load");
    auto analyse = make(&Pipeline::analyse, &StageSeconds::analyse, "analyse");
    auto lods = make(&Pipeline::lods, &StageSeconds::lods, "simplify");
    // After post-process the job goes to two branches at once: whether it gets pictures is settled here, before
    // either branch can change it.
    auto post = std::make_unique<Node>(
        g, flow::unlimited,
        [&pipeline, body = stage([&pipeline](Job& j) { pipeline.post_process(j); }, &StageSeconds::post_process,
                                 "post-process", timeout_s, options)](JobPtr job) {
          job = body(std::move(job));
          job->picture_wanted = !job->finished && pipeline.wants_pictures(*job);
          return job;
        });
    auto measure = make(&Pipeline::measure, &StageSeconds::measure, "evaluate");
    auto write = make(&Pipeline::write, &StageSeconds::write, "write");
    Node pictures(g, flow::unlimited, [](JobPtr job) {
      if (job->picture_wanted) {
        const auto t = Clock::now();
        Pipeline::pictures(*job);
        job->stages.pictures += seconds_since(t);
      }
      return job;
    });
    using Gather = flow::multifunction_node<JobPtr, std::tuple<JobPtr>>;
    Gather gather(g, flow::unlimited, [&pipeline](const JobPtr& job, Gather::output_ports_type& ports) {
      if (job->arrivals.fetch_sub(1, std::memory_order_acq_rel) != 1) return;
      pipeline.finish_pictures(*job);
      std::get<0>(ports).try_put(job);
    });

    auto start = [&](const std::vector<Pending>& batch) {
      for (const Pending& p : batch) {
        auto job = std::make_shared<Job>();
        job->index = p.index;
        job->path = p.path;
        job->file = options.input_dir / p.path;
        job->cls = p.cls;
        job->footprint = p.footprint;
        job->record = base_record(p.path, p.cls);
        fingerprint->try_put(std::move(job));
      }
    };
    // Serial: records, counters and the observer see one asset at a time.
    flow::function_node<JobPtr, flow::continue_msg> report(g, flow::serial, [&](const JobPtr& job) {
      // This run's work on the asset (also for a cache hit: its lookup), not the time it waited for a thread.
      job->record["seconds"] = work_seconds(job->stages);
      result.pictured_assets += job->record.contains("pictures") && job->record["cache_hit"] == false;
      records[job->index] = std::move(job->record);
      const StageSeconds& s = job->stages;
      StageSeconds& total = result.stages;
      total.fingerprint += s.fingerprint, total.load += s.load, total.analyse += s.analyse, total.lods += s.lods;
      total.post_process += s.post_process, total.measure += s.measure, total.write += s.write;
      total.pictures += s.pictures;
      triangles_done += job->processed_triangles;
      ++done;
      // Free the asset's meshes before more assets are admitted against its budget.
      const std::uint64_t footprint = job->footprint;
      const std::size_t index = job->index;
      job->asset = {};
      job->chains.clear();
      job->sources.clear();
      job->levels.clear();
      job->conservative_built.clear();
      job->conservative.clear();
      if (footprint >= kTrimAfterFootprint) release_free_memory();
      if (options.on_asset_done) {
        try {
          options.on_asset_done(AssetDone{.record = records[index],
                                          .done = done,
                                          .total = paths.size(),
                                          .input_triangles_done = triangles_done,
                                          .elapsed_seconds = seconds_since(t0)});
        } catch (...) {
          // Progress output is best effort: a failing observer must not stop the graph.
        }
      }
      admission.release(footprint);
      start(admission.take());
      return flow::continue_msg();
    });
    flow::make_edge(*fingerprint, *load);
    flow::make_edge(*load, *analyse);
    flow::make_edge(*analyse, *lods);
    flow::make_edge(*lods, *post);
    flow::make_edge(*post, *measure);
    flow::make_edge(*post, pictures);
    flow::make_edge(*measure, *write);
    flow::make_edge(*write, gather);
    flow::make_edge(pictures, gather);
    flow::make_edge(flow::output_port<0>(gather), report);
    start(admission.take());
    g.wait_for_all();
  });
  cache.remove_empty_staging();

  for (const Pending& p : admission.left()) {
    records[p.index] = base_record(p.path, p.cls);
    records[p.index]["status"] = "not_started";
    records[p.index]["error"] = "not started: the run was stopped before this asset";
    result.cancelled = true;
  }

  // Status and outputs of each asset, kept for the stale-output check (the records move into the report).
  std::vector<Json> records_for_stale(records.size());
  for (std::size_t i = 0; i < records.size(); ++i) {
    records_for_stale[i] = {{"status", records[i]["status"]}, {"outputs", records[i]["outputs"]}};
  }
  Json assets = Json::array();
  for (std::size_t i = 0; i < records.size(); ++i) {
    const Json& r = records[i];
    const std::string status = r["status"];
    if (status == "ok")
      ++result.succeeded;
    else if (status == "failed") {
      ++result.failed;
      result.failures.push_back(paths[i] + ": " + r["error"].get<std::string>());
    } else if (status == "not_started") {
      ++result.not_started;
    } else {
      ++result.skipped;
      result.skipped_assets.push_back(paths[i] + ": " + r["error"].get<std::string>());
    }
    if (r["cache_hit"].get<bool>()) ++result.cache_hits;
    assets.push_back(std::move(records[i]));
  }
  // Stale outputs are judged only where this run sees every asset: a shard does not know the others' outputs.
  if (!options.shard) {
    result.stale_outputs = stale_outputs(options.output_dir, options.input_dir, cache, paths, records_for_stale);
    if (options.prune) {
      remove_outputs(options.output_dir, result.stale_outputs);
      const std::set<std::string> library(paths.begin(), paths.end());
      for (const std::string& p : cache.entry_paths()) {
        if (!library.count(p)) cache.remove_entry(p);
      }
      result.pruned = true;
    }
  }
  result.input_triangles = triangles_done;
  result.seconds = seconds_since(t0);

  Json report = Json::object();
  report["lodforge_version"] = kLodforgeVersion;
  report["config_file"] = options.config_file.generic_string();
  report["effective_config"] = effective_config_json(config);
  report["jobs"] = jobs;
  report["shard"] = options.shard ? Json(shard_name(*options.shard)) : Json(nullptr);
  report["input_dir"] = options.input_dir.generic_string();
  report["output_dir"] = options.output_dir.generic_string();
  report["summary"] = report_summary(assets, result.seconds);
  if (!result.stale_outputs.empty()) {
    report["stale_outputs"] = result.stale_outputs;
    report["stale_outputs_removed"] = result.pruned;
  }
  report["assets"] = std::move(assets);
  if (options.write_report) {
    result.report_path = options.output_dir / (report_stem + ".json");
    // Nightly runs into one output are compared: the report that is about to be replaced is the baseline. One
    // that is unreadable or not a report is no baseline (a first run has none either).
    std::error_code exists_ec;
    if (fs::is_regular_file(result.report_path, exists_ec)) {
      try {
        const Json previous = Json::parse(io::read_file(result.report_path), nullptr, false);
        if (!previous.is_discarded() && check_report(previous).empty()) {
          report["changes"] = diff_reports(previous, report);
        }
      } catch (const io::IoError&) {
        // unreadable: no baseline
      }
    }
    write_report(report, result.report_path, options.output_dir / (report_stem + ".html"));
    // Entries of assets this run does not list stay while their files do: not after --prune, and not in a
    // shard, which cannot tell a removed asset from another shard's.
    const fs::path manifest = options.output_dir / (manifest_stem + ".json");
    const bool keep_unlisted = !options.shard && !options.prune;
    write_lods_manifest(lods_manifest(report, read_lods_manifest(manifest), keep_unlisted), manifest);
  }
  result.report = std::move(report);
  return result;
}

}  // namespace lodforge::batch
