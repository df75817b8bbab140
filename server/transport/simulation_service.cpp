// SimulationService: construction, the job record as a message, and the job RPCs (SubmitJob,
// GetJob, ListJobs, WatchJob, CancelJob, DeleteJob). Results: simulation_service_results.cpp;
// grids: simulation_service_grids.cpp; QueryJobs: simulation_service_query.cpp.
#include "server/transport/simulation_service.hpp"

#include <google/protobuf/util/json_util.h>
#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <thread>

#include "server/log.hpp"
#include "server/store/spec_hash.hpp"
#include "server/transport/resource_name.hpp"
#include "server/transport/rpc_guard.hpp"
#include "server/transport/rpc_support.hpp"

namespace softshock::server {

namespace fs = std::filesystem;
using namespace rpc;
using grpc::Status;
using grpc::StatusCode;

namespace {

// A running job gets this long to stop by itself before CancelJob records the cancellation.
constexpr double kCancelGraceS = 0.8;

// The filters a page token is bound to (AIP-158: other fields must match across pages). Tokens
// of requests without an owner are the same as before owners existed.
std::string list_fingerprint(const v1::ListJobsRequest& req) {
  std::string f = std::to_string(req.state()) + "|" + req.label() + "|";
  if (req.has_created_after()) f += std::to_string(timestamp_us(req.created_after()));
  f += "|";
  if (req.has_created_before()) f += std::to_string(timestamp_us(req.created_before()));
  if (!req.owner().empty()) f += "|" + req.owner();
  return sha256_hex(f).substr(0, 16);
}

}  // namespace

SimulationService::SimulationService(ServiceConfig config, Catalogue& catalogue,
                                     Executor& scheduler, JobEvents& events,
                                     const JobRunner& runner, const Authenticator& auth,
                                     const MeshStore& meshes)
    : config_(config),
      catalogue_(catalogue),
      scheduler_(scheduler),
      events_(events),
      runner_(runner),
      auth_(auth),
      meshes_(meshes),
      id_random_(std::random_device{}()) {
  // Specs are validated against the runner's DATA/meshes/ (mesh_file never leaves it).
  config_.limits.mesh_root = runner_.meshes_dir();
}

std::string SimulationService::new_job_id() {
  std::lock_guard lock(id_mutex_);
  static const char* hex = "0123456789abcdef";
  uint64_t r = id_random_();
  std::string id(16, '0');
  for (int i = 15; i >= 0; --i, r >>= 4) id[i] = hex[r & 0xf];
  return id;
}

void SimulationService::fill_job(const JobRecord& r, v1::Job* job) const {
  job->set_name("jobs/" + r.id);
  job->set_id(r.id);
  job->set_state(static_cast<v1::JobState>(r.state));
  try {
    *job->mutable_spec() = parse_stored_spec(r.spec_json);
  } catch (const SpecError& e) {
    log_warning("job ", r.id, ": ", e.what());
  }
  job->mutable_labels()->insert(r.labels.begin(), r.labels.end());
  job->set_priority(r.priority);
  set_timestamp(r.create_us, job->mutable_create_time());
  if (r.start_us) set_timestamp(r.start_us, job->mutable_start_time());
  if (r.finish_us) set_timestamp(r.finish_us, job->mutable_finish_time());
  JobProgressRecord p = r.progress;
  if (r.state == JobState::kRunning) {
    if (auto live = events_.progress(r.id)) p = *live;
  }
  auto* progress = job->mutable_progress();
  progress->set_fraction(p.fraction);
  progress->set_simulated_time(p.simulated_time_s);
  progress->set_steps(p.steps);
  progress->set_dt(p.dt_s);
  // The server's own folders stay private: result_path is relative to the data folder, and
  // an error naming a file there says DATA/ instead.
  job->set_error(without_data_dir(r.error, "DATA/"));
  job->set_reason(r.reason);
  job->set_result_path(without_data_dir(r.result_path, ""));
  job->set_attempt(r.attempt);
  job->set_request_id(r.request_id);
  job->set_spec_hash(r.spec_hash);
  job->set_grid_id(r.grid_id);
  job->set_grid_index(r.grid_index);
  job->set_reused_from(r.reused_from);
  job->set_owner(r.owner);
  job->set_parent_id(r.parent_id);
}

std::string SimulationService::without_data_dir(const std::string& text,
                                                const std::string& replacement) const {
  const std::string prefix = runner_.data_dir() + "/";
  std::string out = text;
  for (auto at = out.find(prefix); at != std::string::npos;
       at = out.find(prefix, at + replacement.size())) {
    out.replace(at, prefix.size(), replacement);
  }
  return out;
}

std::optional<JobRecord> SimulationService::wait_terminal(const std::string& id,
                                                          double seconds) const {
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                            std::chrono::duration<double>(seconds));
  for (;;) {
    const uint64_t seen = events_.version(id);
    auto record = catalogue_.get(id);
    if (!record || is_terminal(record->state)) return record;
    const auto now = std::chrono::steady_clock::now();
    if (now >= deadline || events_.shutting_down()) return record;
    events_.wait(id, seen, std::min(deadline, now + std::chrono::milliseconds(100)));
  }
}

// --- SubmitJob -----------------------------------------------------------------------------

Status SimulationService::SubmitJob(grpc::ServerContext* ctx, const v1::SubmitJobRequest* req,
                                    v1::Job* resp) {
  return audited(auth_, ctx, "SubmitJob", [&](const Caller& caller, AuditRecord& audit) {
    auto hold = meshes_.hold_for_submit();  // its mesh cannot be deleted before the insert
    return submit(ctx, caller, *req, resp, audit);
  });
}

Status SimulationService::submit(grpc::ServerContext* ctx, const Caller& caller,
                                 const v1::SubmitJobRequest& req, v1::Job* resp, AuditRecord& audit,
                                 const std::string& parent_id) {
  if (Status s = check_request_id_and_labels(req.request_id(), req.labels()); !s.ok()) return s;
  // A repeated request_id returns the first job, even when the queue is full (AIP-155).
  if (!req.request_id().empty()) {
    if (auto existing = catalogue_.find_by_request_id(req.request_id())) {
      audit.resource = "jobs/" + existing->id;
      audit.detail = "repeat=request_id";
      fill_job(*existing, resp);
      return Status::OK;
    }
  }
  // No new work while the disk is below its reserve: it could not run, and the catalogue keeps
  // its room (a full disk also fails the insert itself: CatalogueFull).
  runner_.require_free_space();
  catalogue_.keep_room();  // taken back first if a full disk used it
  CanonicalSpec spec;
  try {
    spec = daemon_canonical_spec(req.spec(), config_.limits, meshes_);
    check_spec_admission(spec.spec, config_.admission);
  } catch (const SpecError& e) {
    return spec_invalid(ctx, "spec", e);
  }
  NewJob job;
  job.spec_json = spec.json;
  job.spec_hash = spec.hash;
  job.groups = spec_groups(spec.spec);
  job.request_id = req.request_id();
  job.labels.insert(req.labels().begin(), req.labels().end());
  job.priority = req.priority();
  job.reuse_result = req.reuse_result();
  job.owner = caller.user;
  job.parent_id = parent_id;

  if (!scheduler_.reserve()) {
    return {StatusCode::RESOURCE_EXHAUSTED, "the queue is full (" +
                                                std::to_string(scheduler_.queued()) +
                                                " jobs waiting); retry later"};
  }
  Catalogue::InsertResult inserted;
  try {
    // A random id can collide (2^-64); the UNIQUE constraint catches it and we draw again.
    for (int tries = 0;; ++tries) {
      job.id = new_job_id();
      job.create_us = now_us();
      try {
        inserted = catalogue_.insert(job, config_.quotas.max_queued_per_user);
        break;
      } catch (const CatalogueError&) {
        if (tries >= 2 || catalogue_.get(job.id) == std::nullopt) throw;
      }
    }
  } catch (...) {
    scheduler_.release();
    throw;
  }
  if (inserted.refused) {
    scheduler_.release();
    throw_queued_quota(config_.quotas, caller.user, inserted.owner_queued, 1);
  }
  audit.resource = "jobs/" + inserted.job.id;
  if (!inserted.created) {
    scheduler_.release();  // raced with the same request_id
  } else if (job.reuse_result && runner_.reuse_identical(inserted.job)) {
    scheduler_.release();
    inserted.job = catalogue_.get(inserted.job.id).value_or(inserted.job);
  } else {
    scheduler_.enqueue(inserted.job.id, inserted.job.priority, inserted.job.seq, true);
    events_.notify(inserted.job.id);
    log_info("job ", inserted.job.id, " submitted by ", caller.user, " (priority ",
             inserted.job.priority, ", spec ", inserted.job.spec_hash.substr(0, 12), ")");
  }
  fill_job(inserted.job, resp);
  return Status::OK;
}

// --- ExtendJob -----------------------------------------------------------------------------

// A submission of the parent's spec to the later end time, linked to the parent: the runner
// continues from the parent's final state (jobs/job_checkpoint.hpp) when it can.
Status SimulationService::ExtendJob(grpc::ServerContext* ctx, const v1::ExtendJobRequest* req,
                                    v1::Job* resp) {
  return audited(auth_, ctx, "ExtendJob", [&](const Caller& caller, AuditRecord& audit) -> Status {
    std::string id;
    if (Status st = requested_id(*req, "jobs/", &id); !st.ok()) return st;
    const auto parent = catalogue_.get(id);
    if (!parent) return not_found(id);
    audit.resource = "jobs/" + id;
    if (parent->state != JobState::kSucceeded) {
      return {StatusCode::FAILED_PRECONDITION, "job " + id + " is " +
                                                   std::string(to_string(parent->state)) +
                                                   ": only a SUCCEEDED job can be extended"};
    }
    v1::SubmitJobRequest extended;
    try {
      *extended.mutable_spec() = parse_stored_spec(parent->spec_json);
    } catch (const SpecError&) {
      return {StatusCode::INTERNAL, "job " + id + ": its stored spec does not parse"};
    }
    const double parent_end = extended.spec().run().end_time();
    if (!(req->end_time() > parent_end)) {
      char rule[96];
      std::snprintf(rule, sizeof rule, "must be after the parent's end time, %.6g s", parent_end);
      return invalid("end_time", rule);
    }
    extended.mutable_spec()->mutable_run()->set_end_time(req->end_time());
    extended.mutable_labels()->insert(req->labels().begin(), req->labels().end());
    extended.set_priority(req->priority());
    extended.set_request_id(req->request_id());
    auto hold = meshes_.hold_for_submit();  // its mesh cannot be deleted before the insert
    return submit(ctx, caller, extended, resp, audit, id);
  });
}

// --- GetJob / ListJobs ---------------------------------------------------------------------

Status SimulationService::GetJob(grpc::ServerContext* ctx, const v1::GetJobRequest* req,
                                 v1::Job* resp) {
  return guarded(auth_, ctx, "GetJob", [&]() -> Status {
    std::string id;
    if (Status st = requested_id(*req, "jobs/", &id); !st.ok()) return st;
    auto record = catalogue_.get(id);
    if (!record) return not_found(id);
    fill_job(*record, resp);
    return Status::OK;
  });
}

Status SimulationService::ListJobs(grpc::ServerContext* ctx, const v1::ListJobsRequest* req,
                                   v1::ListJobsResponse* resp) {
  return guarded(auth_, ctx, "ListJobs", [&] { return list(*req, resp); });
}

Status SimulationService::list(const v1::ListJobsRequest& req, v1::ListJobsResponse* resp) {
  for (const auto& [given, t, field] :
       {std::tuple{req.has_created_after(), &req.created_after(), "created_after"},
        std::tuple{req.has_created_before(), &req.created_before(), "created_before"}}) {
    if (given && !valid_timestamp(*t)) {
      return invalid(field, "must be a timestamp between years 1 and 9999 (nanos 0..999999999)");
    }
  }
  int page_size = 0;
  if (Status s = page_size_of(req.page_size(), &page_size); !s.ok()) return s;
  ListFilter filter;
  if (req.state() != v1::JOB_STATE_UNSPECIFIED) {
    if (req.state() < v1::QUEUED || req.state() > v1::CANCELLED) {
      return invalid("state", "unknown state " + std::to_string(req.state()));
    }
    filter.state = static_cast<JobState>(req.state());
  }
  if (!req.label().empty()) {
    const auto eq = req.label().find('=');
    filter.label_key = req.label().substr(0, eq);
    if (filter.label_key.empty()) return invalid("label", "expected key=value or key");
    if (eq != std::string::npos) filter.label_value = req.label().substr(eq + 1);
  }
  if (req.has_created_after()) filter.created_after_us = timestamp_us(req.created_after());
  if (req.has_created_before()) filter.created_before_us = timestamp_us(req.created_before());
  if (Status s = check_owner_filter(req.owner()); !s.ok()) return s;
  filter.owner = req.owner();
  const std::string fingerprint = list_fingerprint(req);
  std::string cursor;
  if (Status s = read_page_token(req.page_token(), fingerprint, &cursor); !s.ok()) return s;
  if (!cursor.empty() && !parse_seq_cursor(cursor, &filter.before_seq)) {
    return invalid("page_token", "not a token this server issued");
  }
  filter.limit = page_size + 1;  // one extra row tells whether another page exists
  auto rows = catalogue_.list(filter);
  bool more = static_cast<int>(rows.size()) > page_size;
  if (more) rows.resize(static_cast<std::size_t>(page_size));
  PageBudget budget;
  int64_t last_seq = 0;
  for (const auto& r : rows) {
    v1::Job job;
    fill_job(r, &job);
    if (!budget.take(job.ByteSizeLong())) {
      more = true;  // the rest comes on the next page
      break;
    }
    *resp->add_jobs() = std::move(job);
    last_seq = r.seq;
  }
  if (more) resp->set_next_page_token(make_page_token(std::to_string(last_seq), fingerprint));
  return Status::OK;
}

// --- WatchJob ------------------------------------------------------------------------------

Status SimulationService::WatchJob(grpc::ServerContext* ctx, const v1::WatchJobRequest* req,
                                   grpc::ServerWriter<v1::Job>* writer) {
  return guarded(auth_, ctx, "WatchJob", [&]() -> Status {
    std::string id;
    if (Status st = requested_id(*req, "jobs/", &id); !st.ok()) return st;
    StreamSlot slot(*this);
    if (!slot.acquired()) {
      return {StatusCode::RESOURCE_EXHAUSTED,
              "too many concurrent streams (" + std::to_string(config_.max_streams) + ")"};
    }
    return watch(ctx, id, writer);
  });
}

Status SimulationService::watch(grpc::ServerContext* ctx, const std::string& id,
                                grpc::ServerWriter<v1::Job>* writer) {
  using Clock = std::chrono::steady_clock;
  const auto min_interval = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(config_.watch_min_interval_s));
  std::string last_sent;
  Clock::time_point last_send_time{};
  bool first = true;
  for (;;) {
    if (ctx->IsCancelled()) return {StatusCode::CANCELLED, "watch cancelled by the client"};
    if (events_.shutting_down()) return {StatusCode::UNAVAILABLE, "server shutting down"};
    const uint64_t seen = events_.version(id);
    auto record = catalogue_.get(id);
    if (!record) return first ? not_found(id) : Status(StatusCode::NOT_FOUND, "job deleted");
    first = false;
    v1::Job job;
    fill_job(*record, &job);
    std::string bytes = job.SerializeAsString();
    if (bytes != last_sent) {
      if (!writer->Write(job)) return {StatusCode::CANCELLED, "client went away"};
      last_sent = std::move(bytes);
      last_send_time = Clock::now();
    }
    if (is_terminal(record->state)) return Status::OK;
    // Sleep until something changes; wake once a second regardless to notice a cancelled
    // client (and changes the version counter cannot see, e.g. after a restart).
    events_.wait(id, seen, Clock::now() + std::chrono::seconds(1));
    // Throttle: at most one update per min_interval; state changes are picked up next read.
    const auto next_allowed = last_send_time + min_interval;
    while (Clock::now() < next_allowed && !ctx->IsCancelled() && !events_.shutting_down()) {
      std::this_thread::sleep_for(
          std::min<Clock::duration>(next_allowed - Clock::now(), std::chrono::milliseconds(50)));
    }
  }
}

// --- CancelJob / DeleteJob -----------------------------------------------------------------

Status SimulationService::CancelJob(grpc::ServerContext* ctx, const v1::CancelJobRequest* req,
                                    v1::Job* resp) {
  return audited(auth_, ctx, "CancelJob", [&](const Caller& caller, AuditRecord& audit) -> Status {
    std::string id;
    if (Status st = requested_id(*req, "jobs/", &id); !st.ok()) return st;
    audit.resource = "jobs/" + id;
    return cancel(caller, id, resp);
  });
}

Status SimulationService::cancel(const Caller& caller, const std::string& id, v1::Job* resp) {
  auto record = catalogue_.get(id);
  if (!record) return not_found(id);
  require_may_modify(caller, "jobs/" + id, record->owner, "cancel");
  if (is_terminal(record->state)) {
    return {StatusCode::FAILED_PRECONDITION,
            "job " + id + " is already " + to_string(record->state)};
  }
  if (record->state == JobState::kQueued && catalogue_.cancel_queued(id, now_us())) {
    scheduler_.cancel(id, StopReason::kUser);  // drop it from the queue
    events_.forget(id);
    log_info("job ", id, " CANCELLED while queued");
  } else {
    // Running (or a worker just picked it up): the solver checks the flag every step and
    // normally stops within milliseconds, keeping its partial result.
    scheduler_.cancel(id, StopReason::kUser);
    record = wait_terminal(id, std::min(config_.cancel_wait_s, kCancelGraceS));
    if (!record) return not_found(id);
    if (record->state == JobState::kRunning) {
      // Still in an uninterruptible phase (Gmsh meshing): record the cancellation now so it
      // takes effect within a second; the worker's own conditional update then loses the race
      // and it drops the job when meshing returns.
      if (catalogue_.finish(id, record->attempt, JobState::kCancelled, reason::kCancelledByUser,
                            "cancelled by user while the worker was meshing", "",
                            events_.progress(id).value_or(JobProgressRecord{}), nullptr,
                            now_us())) {
        log_info("job ", id, " CANCELLED while meshing (worker stops when Gmsh returns)");
      }
      events_.forget(id);
    }
  }
  record = catalogue_.get(id);
  if (!record) return not_found(id);
  fill_job(*record, resp);
  return Status::OK;
}

Status SimulationService::DeleteJob(grpc::ServerContext* ctx, const v1::DeleteJobRequest* req,
                                    v1::DeleteJobResponse*) {
  return audited(auth_, ctx, "DeleteJob", [&](const Caller& caller, AuditRecord& audit) -> Status {
    std::string id;
    if (Status st = requested_id(*req, "jobs/", &id); !st.ok()) return st;
    audit.resource = "jobs/" + id;
    return erase(caller, id);
  });
}

Status SimulationService::erase(const Caller& caller, const std::string& id) {
  auto record = catalogue_.get(id);
  if (!record) return not_found(id);
  require_may_modify(caller, "jobs/" + id, record->owner, "delete");
  if (!is_terminal(record->state)) {
    v1::Job ignored;
    if (Status s = cancel(caller, id, &ignored);
        !s.ok() && s.error_code() != StatusCode::NOT_FOUND) {
      return s;
    }
    record = catalogue_.get(id);
    if (record && !is_terminal(record->state)) {
      return {StatusCode::FAILED_PRECONDITION,
              "job " + id + " is still stopping; retry DeleteJob in a few seconds"};
    }
  }
  // Works on a full disk: the catalogue uses its reserved room if it must (catalogue_room.hpp).
  catalogue_.erase(id);
  // Rows first, then files: a crash in between leaves an orphan folder, which the next
  // start-up removes; the other order could leave a row pointing at nothing.
  std::error_code ec;
  fs::remove_all(runner_.job_dir(id), ec);
  if (ec) log_warning("job ", id, ": removing ", runner_.job_dir(id), ": ", ec.message());
  events_.forget(id);
  // The space just freed first gives the catalogue back the room it may have used.
  catalogue_.keep_room();
  log_info("job ", id, " deleted");
  return Status::OK;
}

// --- GetCaller ------------------------------------------------------------------------------

Status SimulationService::GetCaller(grpc::ServerContext* ctx, const v1::GetCallerRequest*,
                                    v1::Caller* resp) {
  return guarded(auth_, ctx, "GetCaller", [&](const Caller& caller) {
    resp->set_user(caller.user);
    resp->set_role(to_string(caller.role));
    return Status::OK;
  });
}

}  // namespace softshock::server
