// SimulationService's UpdateJobLabels: labels set and removed after submission, by the job's
// owner (or an admin), under SubmitJob's label rules, audited like every change.
#include <grpcpp/grpcpp.h>

#include <map>
#include <string>
#include <vector>

#include "server/log.hpp"
#include "server/transport/resource_name.hpp"
#include "server/transport/rpc_guard.hpp"
#include "server/transport/rpc_support.hpp"
#include "server/transport/simulation_service.hpp"

namespace softshock::server {

using namespace rpc;
using grpc::Status;
using grpc::StatusCode;

Status SimulationService::UpdateJobLabels(grpc::ServerContext* ctx,
                                          const v1::UpdateJobLabelsRequest* req, v1::Job* resp) {
  return audited(
      auth_, ctx, "UpdateJobLabels", [&](const Caller& caller, AuditRecord& audit) -> Status {
        std::string id;
        if (Status st = requested_id(*req, "jobs/", &id); !st.ok()) return st;
        audit.resource = "jobs/" + id;
        audit.detail = "set=" + std::to_string(req->set().size()) +
                       " remove=" + std::to_string(req->remove().size());
        if (req->set().empty() && req->remove().empty()) {
          return invalid("set", "give labels to set or keys to remove");
        }
        if (Status s = check_labels("set", req->set()); !s.ok()) return s;
        std::vector<std::string> remove;
        for (const auto& key : req->remove()) {
          if (key.empty() || key.find('=') != std::string::npos) {
            return invalid("remove",
                           "'" + key + "' is not a label key (1..63 characters without '=')");
          }
          if (req->set().count(key)) {
            return invalid("remove", "'" + key + "' is also in set: set it or remove it");
          }
          remove.push_back(key);
        }
        auto record = catalogue_.get(id);
        if (!record) return not_found(id);
        require_may_modify(caller, "jobs/" + id, record->owner, "relabel");
        const std::map<std::string, std::string> set(req->set().begin(), req->set().end());
        auto updated = catalogue_.update_labels(id, set, remove, kMaxLabels);
        if (updated.too_many > 0) {
          return invalid("set", "the job would have " + std::to_string(updated.too_many) +
                                    " labels, more than " + std::to_string(kMaxLabels) +
                                    "; remove some first");
        }
        if (!updated.job) return not_found(id);  // deleted meanwhile
        fill_job(*updated.job, resp);
        log_info("job ", id, " labels changed by ", caller.user);
        return Status::OK;
      });
}

}  // namespace softshock::server
