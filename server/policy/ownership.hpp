// Who may change what: every job, grid and mesh has an owner (the user who submitted or uploaded
// it); every user may read everything, but cancels and deletes only what they own, and an admin
// anything. The one place this rule is written down; the RPC handlers ask it before any change.
#pragma once

#include <stdexcept>
#include <string>

#include "server/policy/users.hpp"

namespace softshock::server {

// A caller tried to change what another user owns. The RPC wrapper answers PERMISSION_DENIED
// with the message (server/transport/rpc_guard.hpp).
class PermissionDenied : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

bool may_modify(const Caller& caller, const std::string& owner);

// Throws PermissionDenied unless `caller` may modify `resource` ("jobs/ID", "grids/ID",
// "meshes/ID"), which `owner` owns; `action` is the verb refused ("cancel", "delete").
void require_may_modify(const Caller& caller, const std::string& resource, const std::string& owner,
                        const char* action);

}  // namespace softshock::server
