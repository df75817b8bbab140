#include "server/policy/quotas.hpp"

#include <cstdio>

#include "server/byte_size.hpp"
#include "server/store/resource_exhausted.hpp"

namespace softshock::server {

void throw_queued_quota(const QuotaLimits& limits, const std::string& user, std::int64_t queued,
                        std::int64_t adding) {
  throw ResourceExhausted(
      "user " + user + " has " + std::to_string(queued) + " job(s) queued; " +
      std::to_string(adding) +
      " more would pass max-queued-per-user = " + std::to_string(limits.max_queued_per_user) +
      ": wait until some have started, or cancel or delete queued ones (softshock list --owner " +
      user + " --state QUEUED)");
}

void check_mesh_quota(const QuotaLimits& limits, const std::string& user, const MeshUsage& of_user,
                      const MeshUsage& total, std::int64_t bytes) {
  const std::string free_some =
      ": delete meshes no job needs any more (softshock mesh list --owner " + user +
      "; softshock mesh delete ID)";
  if (of_user.count + 1 > limits.max_meshes_per_user) {
    throw ResourceExhausted("user " + user + " stores " + std::to_string(of_user.count) +
                            " mesh(es), the most max-meshes-per-user = " +
                            std::to_string(limits.max_meshes_per_user) + " allows" + free_some);
  }
  if (of_user.bytes + bytes > limits.max_mesh_bytes_per_user) {
    throw ResourceExhausted("user " + user + "'s meshes take " + byte_size(of_user.bytes) +
                            "; this one (" + byte_size(bytes) +
                            ") would pass max-mesh-bytes-per-user = " +
                            byte_size(limits.max_mesh_bytes_per_user) + free_some);
  }
  const std::string ask = ", or ask an admin to delete unused meshes of other users";
  if (total.count + 1 > limits.max_meshes) {
    throw ResourceExhausted("the daemon stores " + std::to_string(total.count) +
                            " uploaded mesh(es), the most max-meshes = " +
                            std::to_string(limits.max_meshes) + " allows" + free_some + ask);
  }
  if (total.bytes + bytes > limits.max_mesh_bytes) {
    throw ResourceExhausted("the daemon's uploaded meshes take " + byte_size(total.bytes) +
                            "; this one (" + byte_size(bytes) + ") would pass max-mesh-bytes = " +
                            byte_size(limits.max_mesh_bytes) + free_some + ask);
  }
}

}  // namespace softshock::server
