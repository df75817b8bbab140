// What one user, and all users together, may keep on a shared daemon: queued jobs, and uploaded
// meshes by count and bytes. The bounds are daemon settings (server/daemon_config.hpp); the store
// counts atomically (Catalogue::insert, MeshStore::commit) and these functions word the refusal:
// a ResourceExhausted (RESOURCE_EXHAUSTED) that names the bound, the figure, and how to get
// below it. The global bound on queued jobs is the scheduler's (--max-queued).
#pragma once

#include <cstdint>
#include <string>

namespace softshock::server {

struct QuotaLimits {
  std::int64_t max_queued_per_user = 500;  // QUEUED jobs (grid points included) of one owner
  std::int64_t max_meshes = 1000;          // uploaded meshes stored, all users
  std::int64_t max_meshes_per_user = 100;
  std::int64_t max_mesh_bytes = std::int64_t{8} << 30;  // their bytes, all users
  std::int64_t max_mesh_bytes_per_user = std::int64_t{1} << 30;
};

struct MeshUsage {
  std::int64_t count = 0, bytes = 0;
};

// Throws ResourceExhausted: `user` has `queued` jobs waiting and `adding` more would pass
// limits.max_queued_per_user.
[[noreturn]] void throw_queued_quota(const QuotaLimits& limits, const std::string& user,
                                     std::int64_t queued, std::int64_t adding);

// Throws ResourceExhausted when one more mesh of `bytes` for `user` (who has `of_user`, of
// `total` for everyone) would pass a bound.
void check_mesh_quota(const QuotaLimits& limits, const std::string& user, const MeshUsage& of_user,
                      const MeshUsage& total, std::int64_t bytes);

}  // namespace softshock::server
