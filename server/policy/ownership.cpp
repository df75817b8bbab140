#include "server/policy/ownership.hpp"

namespace softshock::server {

bool may_modify(const Caller& caller, const std::string& owner) {
  return caller.is_admin() || caller.user == owner;
}

void require_may_modify(const Caller& caller, const std::string& resource, const std::string& owner,
                        const char* action) {
  if (may_modify(caller, owner)) return;
  throw PermissionDenied(resource + " is owned by " + owner + ": " + caller.user + " may " +
                         action + " only their own jobs, grids and meshes (an admin may " + action +
                         " any)");
}

}  // namespace softshock::server
