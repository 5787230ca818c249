// Sharding a library across machines: `lodforge run --shard K/N` processes the assets whose relative path
// hashes to K modulo N, so N independent jobs (Slurm array tasks, Kubernetes indexed-job pods, CI matrix
// entries) together cover the library exactly once with no coordination. docs/cluster.md shows the recipes.
//
//   const Shard shard = parse_shard("0/3");          // K is 0-based: 0/3, 1/3 and 2/3 cover everything
//   if (in_shard(shard, "props/crate.obj")) { ... }
//
// K is 0-based because the schedulers' own indices are (JOB_COMPLETION_INDEX, `--array=0-N` task ids), so a job
// script passes its index through unchanged.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

namespace lodforge::batch {

struct Shard {
  std::uint32_t index = 0;  // K, 0 <= K < N
  std::uint32_t count = 1;  // N >= 1
  friend bool operator==(const Shard&, const Shard&) = default;
};

// Parses "K/N" (decimal, 0 <= K < N, N <= 1000000). Throws std::invalid_argument naming the problem.
Shard parse_shard(std::string_view text);
std::string shard_name(const Shard& shard);  // "K/N"

// 64-bit FNV-1a of the '/'-separated relative path: fixed by definition, so every machine, compiler and run
// splits a library the same way.
std::uint64_t path_hash(std::string_view relative_path);
bool in_shard(const Shard& shard, std::string_view relative_path);

}  // namespace lodforge::batch
