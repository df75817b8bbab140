// SimulationService's QueryJobs: filters and an order over the groups and summary figures,
// answered from the catalogue's query columns, with keyset page tokens.
#include <grpcpp/grpcpp.h>

#include <cmath>
#include <cstdio>
#include <sstream>

#include "server/store/spec_hash.hpp"
#include "server/transport/resource_name.hpp"
#include "server/transport/rpc_guard.hpp"
#include "server/transport/rpc_support.hpp"
#include "server/transport/simulation_service.hpp"
#include "solver/summary_figures.hpp"

namespace softshock::server {

using namespace rpc;
using grpc::Status;
using grpc::StatusCode;

// --- QueryJobs -----------------------------------------------------------------------------

Status SimulationService::QueryJobs(grpc::ServerContext* ctx, const v1::QueryJobsRequest* req,
                                    v1::QueryJobsResponse* resp) {
  return guarded(auth_, ctx, "QueryJobs", [&] { return query(*req, resp); });
}

Status SimulationService::query(const v1::QueryJobsRequest& req, v1::QueryJobsResponse* resp) {
  constexpr int kMaxFilters = 16;
  const auto& names = query_column_names();
  // The names of figures renamed with units (energy_injected -> energy_injected_J_per_m, ...)
  // are accepted in their older spelling too.
  auto known = [&](const std::string& n) {
    return std::find(names.begin(), names.end(), current_summary_name(n)) != names.end();
  };
  auto known_list = [&] {
    std::string list;
    for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
    return list;
  };
  int page_size = 0;
  if (Status s = page_size_of(req.page_size(), &page_size); !s.ok()) return s;
  if (req.filters_size() > kMaxFilters) {
    return invalid("filters", "at most " + std::to_string(kMaxFilters) + " filters");
  }
  JobQuery q;
  for (int i = 0; i < req.filters_size(); ++i) {
    const auto& f = req.filters(i);
    const std::string field = "filters[" + std::to_string(i) + "]";
    if (!known(f.name())) {
      return invalid(field + ".name",
                     "unknown name '" + f.name() + "' (known: " + known_list() + ")");
    }
    RangeCondition c;
    c.name = current_summary_name(f.name());
    const std::pair<bool, double> bounds[] = {
        {f.has_gt(), f.gt()}, {f.has_ge(), f.ge()}, {f.has_lt(), f.lt()}, {f.has_le(), f.le()}};
    for (const auto& [given, value] : bounds) {
      if (given && !std::isfinite(value)) return invalid(field, "bounds must be finite");
    }
    if (!f.has_gt() && !f.has_ge() && !f.has_lt() && !f.has_le()) {
      return invalid(field, "give at least one of gt, ge, lt, le");
    }
    if (f.has_gt()) c.gt = f.gt();
    if (f.has_ge()) c.ge = f.ge();
    if (f.has_lt()) c.lt = f.lt();
    if (f.has_le()) c.le = f.le();
    q.conditions.push_back(c);
  }
  if (req.state() != v1::JOB_STATE_UNSPECIFIED) {
    if (req.state() < v1::QUEUED || req.state() > v1::CANCELLED) {
      return invalid("state", "unknown state " + std::to_string(req.state()));
    }
    q.state = static_cast<JobState>(req.state());
  }
  if (!req.grid_id().empty() && !parse_id(req.grid_id(), &q.grid_id, "grids/")) {
    return invalid("grid_id", "not a grid name");
  }
  if (Status s = check_owner_filter(req.owner()); !s.ok()) return s;
  q.owner = req.owner();
  if (!req.order_by().empty()) {
    std::istringstream words(req.order_by());
    std::string column, direction, extra;
    words >> column >> direction >> extra;
    if (!known(column)) {
      return invalid("order_by", "unknown name '" + column + "' (known: " + known_list() + ")");
    }
    if (!extra.empty() || (!direction.empty() && direction != "asc" && direction != "desc")) {
      return invalid("order_by", "expected NAME, NAME asc or NAME desc");
    }
    q.order_by = current_summary_name(column);
    q.descending = direction == "desc";
  }
  v1::QueryJobsRequest shape = req;
  shape.clear_page_size();
  shape.clear_page_token();
  const std::string fingerprint = sha256_hex(shape.SerializeAsString()).substr(0, 16);
  std::string cursor;
  if (Status s = read_page_token(req.page_token(), fingerprint, &cursor); !s.ok()) return s;
  if (!cursor.empty()) {
    // "KEY,SEQ": the sort key's bits in hex (exact), then the row's seq.
    const auto comma = cursor.find(',');
    uint64_t bits = 0;
    if (comma == std::string::npos || !parse_seq_cursor(cursor.substr(comma + 1), &q.after_seq)) {
      return invalid("page_token", "not a token this server issued");
    }
    try {
      bits = std::stoull(cursor.substr(0, comma), nullptr, 16);
    } catch (const std::exception&) {
      return invalid("page_token", "not a token this server issued");
    }
    std::memcpy(&q.after_key, &bits, sizeof bits);
  }
  q.limit = page_size + 1;
  auto rows = catalogue_.query(q);
  bool more = static_cast<int>(rows.size()) > page_size;
  if (more) rows.resize(static_cast<std::size_t>(page_size));
  PageBudget budget;
  const QueryRow* last = nullptr;
  for (const auto& row : rows) {
    v1::QueriedJob out;
    fill_job(row.job, out.mutable_job());
    fill_groups(row.groups, out.mutable_groups());
    if (row.summary) fill_summary(row.job.id, *row.summary, out.mutable_summary());
    if (!budget.take(out.ByteSizeLong())) {
      more = true;
      break;
    }
    *resp->add_jobs() = std::move(out);
    last = &row;
  }
  if (more && last != nullptr) {
    uint64_t bits = 0;
    std::memcpy(&bits, &last->sort_key, sizeof bits);
    std::ostringstream key;
    key << std::hex << bits << "," << std::dec << last->job.seq;
    resp->set_next_page_token(make_page_token(key.str(), fingerprint));
  }
  return Status::OK;
}

// --- ListSummaryFigures -----------------------------------------------------------------------

Status SimulationService::ListSummaryFigures(grpc::ServerContext* ctx,
                                             const v1::ListSummaryFiguresRequest*,
                                             v1::SummaryFigures* resp) {
  return guarded(auth_, ctx, "ListSummaryFigures", [&](const Caller&) {
    for (const auto& f : summary_figures()) {
      if (f.has(kNotInJobSummary)) continue;
      auto* out = resp->add_figures();
      out->set_name(f.name);
      if (f.former) out->set_former_name(f.former);
      out->set_unit(f.unit);
      out->set_meaning(f.meaning);
      out->set_in_groups(f.has(kInGroups));
      out->set_queryable(f.has(kQueryable));
      out->set_grid_quantity(f.has(kGridQuantity));
      out->set_only_3d(f.has(kOnly3D));
      out->set_only_damage(f.has(kOnlyDamage));
      out->set_derived(f.has(kDerived));
    }
    return Status::OK;
  });
}

}  // namespace softshock::server
