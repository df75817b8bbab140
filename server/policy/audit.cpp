#include "server/policy/audit.hpp"

#include "server/log.hpp"

namespace softshock::server {

void audit(const Caller& caller, std::string_view rpc, const AuditRecord& record,
           std::string_view outcome, std::string_view peer) {
  // Appended piece by piece: GCC 12's -Wrestrict misfires on one long concatenation.
  std::string line = "audit user=";
  line += log_field(caller.user);
  line += " role=";
  line += to_string(caller.role);
  line += " rpc=";
  line += log_field(rpc);
  line += " resource=";
  line += log_field(record.resource);
  line += " outcome=";
  line += log_field(outcome);
  if (!record.detail.empty()) {
    line += ' ';
    line += log_field(record.detail);
  }
  line += " peer=";
  line += log_field(peer);
  log_line(LogLevel::kInfo, line);
}

}  // namespace softshock::server
