// Resource names of the API (AIP-122/131): "jobs/{id}" and "grids/{id}". Requests that name a job
// or grid carry `name` (what generic clients and AIP-131 expect) and the older `id`, kept as an
// alias; either may hold the resource name or the bare id.
#pragma once

#include <grpcpp/support/status.h>

#include <cctype>
#include <string>

namespace softshock::server {

// "jobs/{id}" (or "grids/{id}") or the bare id; ids are [A-Za-z0-9_-]{1,64} (they name folders
// on disk).
inline bool parse_id(const std::string& name, std::string* id,
                     const std::string& collection = "jobs/") {
  std::string s = name.rfind(collection, 0) == 0 ? name.substr(collection.size()) : name;
  if (s.empty() || s.size() > 64) return false;
  for (unsigned char c : s) {
    if (!std::isalnum(c) && c != '-' && c != '_') return false;
  }
  *id = std::move(s);
  return true;
}

// The id a request names through `name` or `id`. collection: "jobs/" or "grids/". Errors name the
// field and the rule; both fields set must agree.
inline grpc::Status requested_id(const std::string& name, const std::string& id_alias,
                                 const std::string& collection, std::string* id) {
  const std::string kind = collection == "grids/" ? "grid" : "job";
  const std::string rule =
      "must be " + collection + "{id} or the bare id, id = [A-Za-z0-9_-]{1,64}";
  if (name.empty() && id_alias.empty()) {
    return {grpc::StatusCode::INVALID_ARGUMENT,
            "name: required, the " + kind + "'s resource name " + collection + "{id} (or id)"};
  }
  std::string from_name, from_id;
  if (!name.empty() && !parse_id(name, &from_name, collection)) {
    return {grpc::StatusCode::INVALID_ARGUMENT, "name: '" + name + "' " + rule};
  }
  if (!id_alias.empty() && !parse_id(id_alias, &from_id, collection)) {
    return {grpc::StatusCode::INVALID_ARGUMENT, "id: '" + id_alias + "' " + rule};
  }
  if (!name.empty() && !id_alias.empty() && from_name != from_id) {
    return {grpc::StatusCode::INVALID_ARGUMENT,
            "name: '" + name + "' and id: '" + id_alias + "' name different " + kind + "s"};
  }
  *id = name.empty() ? std::move(from_id) : std::move(from_name);
  return grpc::Status::OK;
}

template <typename Request>
grpc::Status requested_id(const Request& req, const std::string& collection, std::string* id) {
  return requested_id(req.name(), req.id(), collection, id);
}

}  // namespace softshock::server
