// SimulationService's grid RPCs: SubmitGrid (every point checked and admitted, all or
// nothing), GetGrid, ListGrids, CancelGrid and GetGridReduction.
#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "server/jobs/grid.hpp"
#include "server/log.hpp"
#include "server/store/spec_hash.hpp"
#include "server/transport/resource_name.hpp"
#include "server/transport/rpc_guard.hpp"
#include "server/transport/rpc_support.hpp"
#include "server/transport/simulation_service.hpp"

namespace softshock::server {

namespace fs = std::filesystem;
using namespace rpc;
using grpc::Status;
using grpc::StatusCode;

namespace {

// "pbar = 0.5, tbar_pulse = 0.1": point i of a grid (row-major, last axis fastest).
std::string point_coordinates(const GridPlan& plan, std::size_t index) {
  std::string out;
  for (std::size_t a = plan.axes.size(); a-- > 0;) {
    const auto n = static_cast<std::size_t>(plan.shape[a]);
    char value[32];
    std::snprintf(value, sizeof value, "%.6g", plan.axes[a].values(static_cast<int>(index % n)));
    out = plan.axes[a].name() + " = " + value + (out.empty() ? "" : ", ") + out;
    index /= n;
  }
  return out;
}

}  // namespace

// --- Grids ---------------------------------------------------------------------------------

namespace {

Status grid_not_found(const std::string& id) {
  return {StatusCode::NOT_FOUND, "grid " + id + " not found"};
}

// The grid's derived state (see Grid.state in service.proto).
v1::JobState grid_state(const GridCounts& c, int point_count) {
  auto count = [&](JobState s) {
    auto it = c.by_state.find(s);
    return it == c.by_state.end() ? 0 : it->second;
  };
  int present = 0;
  for (const auto& [state, n] : c.by_state) present += n;
  // A deleted point (DeleteJob) will never finish: it counts as finished, with no result.
  const int finished = count(JobState::kSucceeded) + count(JobState::kFailed) +
                       count(JobState::kCancelled) + (point_count - present);
  if (finished < point_count) {
    return count(JobState::kRunning) > 0 || finished > 0 ? v1::RUNNING : v1::QUEUED;
  }
  if (count(JobState::kFailed) > 0) return v1::FAILED;
  if (count(JobState::kCancelled) > 0) return v1::CANCELLED;
  return v1::SUCCEEDED;
}

}  // namespace

void SimulationService::fill_grid(const GridRecord& r, v1::Grid* grid) const {
  google::protobuf::util::JsonParseOptions parse;
  parse.ignore_unknown_fields = true;
  if (!google::protobuf::util::JsonStringToMessage(r.definition, grid, parse).ok()) {
    log_warning("grid ", r.id, ": stored definition does not parse");
  }
  grid->set_name("grids/" + r.id);
  grid->set_id(r.id);
  grid->set_point_count(r.point_count);
  grid->set_request_id(r.request_id);
  grid->set_cancelled(r.cancelled);
  grid->set_owner(r.owner);
  set_timestamp(r.create_us, grid->mutable_create_time());
  const GridCounts c = catalogue_.grid_counts(r.id);
  auto count = [&](JobState s) {
    auto it = c.by_state.find(s);
    return it == c.by_state.end() ? 0 : it->second;
  };
  auto* counts = grid->mutable_counts();
  counts->set_queued(count(JobState::kQueued));
  counts->set_running(count(JobState::kRunning));
  counts->set_succeeded(count(JobState::kSucceeded));
  counts->set_failed(count(JobState::kFailed));
  counts->set_cancelled(count(JobState::kCancelled));
  counts->set_reused(c.reused);
  int present = 0;
  for (const auto& [state, n] : c.by_state) present += n;
  double done =
      counts->succeeded() + counts->failed() + counts->cancelled() + (r.point_count - present);
  for (const auto& id : c.running) {
    if (auto live = events_.progress(id)) done += live->fraction;
  }
  grid->set_progress(r.point_count > 0 ? std::min(1.0, done / r.point_count) : 1.0);
  grid->set_state(grid_state(c, r.point_count));
}

Status SimulationService::SubmitGrid(grpc::ServerContext* ctx, const v1::SubmitGridRequest* req,
                                     v1::Grid* resp) {
  return audited(auth_, ctx, "SubmitGrid", [&](const Caller& caller, AuditRecord& audit) {
    auto hold = meshes_.hold_for_submit();
    return submit_grid(ctx, caller, *req, resp, audit);
  });
}

Status SimulationService::submit_grid(grpc::ServerContext* ctx, const Caller& caller,
                                      const v1::SubmitGridRequest& req, v1::Grid* resp,
                                      AuditRecord& audit) {
  if (Status s = check_request_id_and_labels(req.request_id(), req.labels()); !s.ok()) return s;
  if (!req.request_id().empty()) {
    if (auto existing = catalogue_.find_grid_by_request_id(req.request_id())) {
      audit.resource = "grids/" + existing->id;
      audit.detail = "repeat=request_id";
      fill_grid(*existing, resp);
      return Status::OK;
    }
  }
  runner_.require_free_space();
  catalogue_.keep_room();
  CanonicalSpec base;
  GridPlan plan;
  try {
    base = daemon_canonical_spec(req.base_spec(), config_.limits, meshes_);
  } catch (const SpecError& e) {
    return spec_invalid(ctx, "base_spec", e);
  }
  try {
    plan = expand_grid(base.spec, req.axes(), config_.limits);
    for (std::size_t i = 0; i < plan.points.size(); ++i) {
      try {
        check_spec_admission(plan.points[i].spec, config_.admission);
      } catch (const SpecError& e) {
        throw SpecError(
            "axes", "the point " + point_coordinates(plan, i) + " is refused: spec." + e.what());
      }
    }
  } catch (const SpecError& e) {
    return spec_invalid(ctx, "", e);
  }

  // The definition the grid is stored as: what GetGrid returns besides the live figures.
  v1::Grid definition;
  *definition.mutable_base_spec() = base.spec;
  for (const auto& axis : plan.axes) *definition.add_axes() = axis;
  definition.mutable_shape()->Assign(plan.shape.begin(), plan.shape.end());
  definition.mutable_labels()->insert(req.labels().begin(), req.labels().end());
  definition.set_priority(req.priority());
  definition.set_recompute(req.recompute());
  NewGrid grid;
  grid.id = new_job_id();
  grid.request_id = req.request_id();
  grid.create_us = now_us();
  grid.owner = caller.user;
  (void)google::protobuf::util::MessageToJsonString(definition, &grid.definition);

  // Identical runs are computed once: a point whose canonical spec matches a SUCCEEDED job
  // reuses its result (linked below, before the points are committed).
  std::vector<NewJob> points(plan.points.size());
  std::vector<std::optional<JobRecord>> sources(points.size());
  std::size_t to_run = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    NewJob& p = points[i];
    p.id = new_job_id();
    p.spec_json = plan.points[i].json;
    p.spec_hash = plan.points[i].hash;
    p.groups = spec_groups(plan.points[i].spec);
    p.labels.insert(req.labels().begin(), req.labels().end());
    p.priority = req.priority();
    p.create_us = grid.create_us;
    p.grid_id = grid.id;
    p.grid_index = static_cast<int>(i);
    p.owner = caller.user;
    p.reuse_result = !req.recompute();
    if (p.reuse_result) sources[i] = catalogue_.find_reusable(p.spec_hash);
    if (!sources[i]) ++to_run;
  }
  if (!scheduler_.reserve(to_run)) {
    return {StatusCode::RESOURCE_EXHAUSTED,
            "the queue cannot take " + std::to_string(to_run) + " more jobs (" +
                std::to_string(scheduler_.queued()) + " waiting); retry later"};
  }
  std::size_t reserved = to_run;
  auto remove_links = [&] {
    for (const auto& p : points) {
      std::error_code ec;
      if (!p.reused_from.empty()) fs::remove_all(runner_.job_dir(p.id), ec);
    }
  };
  Catalogue::GridInsertResult inserted;
  try {
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (!sources[i]) continue;
      try {
        points[i].result_path = runner_.link_result(sources[i]->result_path, points[i].id);
        points[i].reused_from = sources[i]->id;
      } catch (const std::exception& e) {
        // The source went away meanwhile: this point runs after all (it tries again at start).
        log_warning("grid ", grid.id, ": cannot reuse ", sources[i]->id, ": ", e.what());
        if (!scheduler_.reserve(1)) throw std::runtime_error("the queue filled up meanwhile");
        ++reserved;
      }
    }
    inserted = catalogue_.insert_grid(grid, points, config_.quotas.max_queued_per_user);
  } catch (...) {
    remove_links();
    scheduler_.release(reserved);
    throw;
  }
  if (inserted.refused) {
    remove_links();
    scheduler_.release(reserved);
    throw_queued_quota(config_.quotas, caller.user, inserted.owner_queued,
                       static_cast<std::int64_t>(reserved));
  }
  audit.resource = "grids/" + inserted.grid.id;
  audit.detail = "points=" + std::to_string(points.size());
  std::size_t reused = 0;
  if (!inserted.created) {
    // Raced with the same request_id: the other submission's grid stands.
    remove_links();
    scheduler_.release(reserved);
  } else {
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (!points[i].reused_from.empty()) {
        ++reused;
        continue;
      }
      scheduler_.enqueue(points[i].id, points[i].priority, inserted.point_seqs[i], true);
    }
    log_info("grid ", grid.id, " submitted by ", caller.user, ": ", points.size(), " points, ",
             reused, " reusing identical runs");
  }
  fill_grid(inserted.grid, resp);
  return Status::OK;
}

Status SimulationService::GetGrid(grpc::ServerContext* ctx, const v1::GetGridRequest* req,
                                  v1::Grid* resp) {
  return guarded(auth_, ctx, "GetGrid", [&]() -> Status {
    std::string id;
    if (Status st = requested_id(*req, "grids/", &id); !st.ok()) return st;
    auto record = catalogue_.get_grid(id);
    if (!record) return grid_not_found(id);
    fill_grid(*record, resp);
    return Status::OK;
  });
}

Status SimulationService::ListGrids(grpc::ServerContext* ctx, const v1::ListGridsRequest* req,
                                    v1::ListGridsResponse* resp) {
  return guarded(auth_, ctx, "ListGrids", [&]() -> Status {
    int page_size = 0;
    if (Status s = page_size_of(req->page_size(), &page_size); !s.ok()) return s;
    if (Status s = check_owner_filter(req->owner()); !s.ok()) return s;
    // Tokens without an owner filter read as before owners existed.
    const std::string fingerprint = req->owner().empty() ? "grids" : "grids|" + req->owner();
    std::string cursor;
    if (Status s = read_page_token(req->page_token(), fingerprint, &cursor); !s.ok()) return s;
    int64_t before_seq = 0;
    if (!cursor.empty() && !parse_seq_cursor(cursor, &before_seq)) {
      return invalid("page_token", "not a token this server issued");
    }
    auto rows = catalogue_.list_grids(before_seq, page_size + 1, req->owner());
    bool more = static_cast<int>(rows.size()) > page_size;
    if (more) rows.resize(static_cast<std::size_t>(page_size));
    PageBudget budget;
    int64_t last_seq = 0;
    for (const auto& r : rows) {
      v1::Grid grid;
      fill_grid(r, &grid);
      if (!budget.take(grid.ByteSizeLong())) {
        more = true;
        break;
      }
      *resp->add_grids() = std::move(grid);
      last_seq = r.seq;
    }
    if (more) resp->set_next_page_token(make_page_token(std::to_string(last_seq), fingerprint));
    return Status::OK;
  });
}

Status SimulationService::CancelGrid(grpc::ServerContext* ctx, const v1::CancelGridRequest* req,
                                     v1::Grid* resp) {
  return audited(auth_, ctx, "CancelGrid", [&](const Caller& caller, AuditRecord& audit) -> Status {
    std::string id;
    if (Status st = requested_id(*req, "grids/", &id); !st.ok()) return st;
    audit.resource = "grids/" + id;
    return cancel_grid(caller, id, resp);
  });
}

Status SimulationService::cancel_grid(const Caller& caller, const std::string& id, v1::Grid* resp) {
  auto record = catalogue_.get_grid(id);
  if (!record) return grid_not_found(id);
  require_may_modify(caller, "grids/" + id, record->owner, "cancel");
  v1::Grid before;
  fill_grid(*record, &before);
  if (before.state() == v1::SUCCEEDED || before.state() == v1::FAILED ||
      before.state() == v1::CANCELLED) {
    return {StatusCode::FAILED_PRECONDITION,
            "grid " + id + " is already " + v1::JobState_Name(before.state())};
  }
  const GridCancellation c = catalogue_.cancel_grid(id, now_us());
  for (const auto& job : c.cancelled) {
    scheduler_.cancel(job, StopReason::kUser);  // drop it from the queue
    events_.forget(job);
  }
  // Running points stop within a step; the answer does not wait for them (GetGrid shows it).
  for (const auto& job : c.running) scheduler_.cancel(job, StopReason::kUser);
  log_info("grid ", id, " cancelled: ", c.cancelled.size(), " queued point(s) cancelled, ",
           c.running.size(), " running point(s) stopping");
  record = catalogue_.get_grid(id);
  if (!record) return grid_not_found(id);
  fill_grid(*record, resp);
  return Status::OK;
}

Status SimulationService::GetGridReduction(grpc::ServerContext* ctx,
                                           const v1::GetGridReductionRequest* req,
                                           v1::GridReduction* resp) {
  return guarded(auth_, ctx, "GetGridReduction", [&] { return grid_reduction(*req, resp); });
}

Status SimulationService::grid_reduction(const v1::GetGridReductionRequest& req,
                                         v1::GridReduction* resp) {
  std::string id;
  if (Status st = requested_id(req, "grids/", &id); !st.ok()) return st;
  const std::string name = req.quantity().empty() ? grid_quantities().front().name : req.quantity();
  const GridQuantity* quantity = find_grid_quantity(name);
  if (quantity == nullptr) {
    std::string known;
    for (const auto& q : grid_quantities())
      known += (known.empty() ? "" : ", ") + std::string(q.name);
    return invalid("quantity", "unknown quantity '" + name + "' (known: " + known + ")");
  }
  if (quantity->needs_tbar && !(req.has_tbar() && std::isfinite(req.tbar()) && req.tbar() >= 0)) {
    return invalid("tbar", "abar_at needs a finite t-bar >= 0");
  }
  auto record = catalogue_.get_grid(id);
  if (!record) return grid_not_found(id);
  v1::Grid grid;
  fill_grid(*record, &grid);
  resp->set_grid_id(id);
  resp->set_quantity(quantity->name);
  resp->set_units(quantity->units);
  resp->set_tbar(quantity->needs_tbar ? req.tbar() : 0.0);
  *resp->mutable_axes() = grid.axes();
  *resp->mutable_shape() = grid.shape();
  const auto n = static_cast<std::size_t>(record->point_count);
  std::vector<double> values(n, NAN);
  std::vector<std::string> ids(n);
  std::vector<int> states(n, v1::JOB_STATE_UNSPECIFIED);  // a deleted point stays unspecified
  for (const auto& p : catalogue_.grid_points(id)) {
    if (p.index < 0 || static_cast<std::size_t>(p.index) >= n) continue;
    ids[p.index] = p.job_id;
    states[p.index] = static_cast<int>(p.state);
    if (p.state == JobState::kSucceeded && p.summary) {
      values[p.index] = grid_quantity(*quantity, *p.summary, req.tbar());
    }
  }
  resp->mutable_values()->Assign(values.begin(), values.end());
  for (std::size_t i = 0; i < n; ++i) {
    resp->add_job_ids(ids[i]);
    resp->add_states(static_cast<v1::JobState>(states[i]));
  }
  return Status::OK;
}

}  // namespace softshock::server
