// The audit trail: one log line per call that changes something (SubmitJob, CancelJob,
// DeleteJob, SubmitGrid, CancelGrid, UploadMesh, DeleteMesh), whatever its outcome:
//   audit user=alice role=user rpc=DeleteJob resource=jobs/0123abcd outcome=PERMISSION_DENIED
//         peer=ipv4:10.0.0.7:51234
// Values are printable ASCII without spaces (server/log.hpp, log_field), so a line splits on
// spaces and '='. Unauthenticated calls never get this far: the transport refuses them before
// any handler and logs them, rate-limited, as `unauthenticated` lines (transport/auth.hpp).
#pragma once

#include <string>
#include <string_view>

#include "server/policy/users.hpp"

namespace softshock::server {

struct AuditRecord {
  std::string resource;  // "jobs/ID", "grids/ID", "meshes/ID"; empty = not known (a bad request)
  std::string detail;    // optional: e.g. "points=40" for a grid
};

void audit(const Caller& caller, std::string_view rpc, const AuditRecord& record,
           std::string_view outcome, std::string_view peer);

}  // namespace softshock::server
