#include "server/transport/simulation_service.hpp"

#include <google/protobuf/util/json_util.h>
#include <google/protobuf/util/time_util.h>
#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <map>
#include <optional>
#include <sstream>
#include <thread>
#include <tuple>

#include "server/jobs/grid.hpp"
#include "server/log.hpp"
#include "server/store/spec_hash.hpp"
#include "server/transport/field_raster.hpp"
#include "server/transport/resource_name.hpp"
#include "server/transport/rpc_guard.hpp"
#include "solver/io/result_file.hpp"

namespace softshock::server {

namespace fs = std::filesystem;
using google::protobuf::util::TimeUtil;
using grpc::Status;
using grpc::StatusCode;

namespace {

constexpr int kDefaultPageSize = 50;
constexpr int kMaxPageSize = 1000;
// A running job gets this long to stop by itself before CancelJob records the cancellation.
constexpr double kCancelGraceS = 0.8;
constexpr std::size_t kMaxLabels = 64;
constexpr std::size_t kMaxLabelKey = 63;
constexpr std::size_t kMaxLabelValue = 255;
constexpr std::size_t kMaxRequestId = 128;
constexpr int kMaxRasterSide = 2048;
constexpr int64_t kMaxRasterCells = 4'194'304;
constexpr std::size_t kChunkDoubles = 65536;         // 512 KiB per FieldChunk
constexpr std::size_t kMaxUnaryDoubles = 4'000'000;  // 32 MiB per TimeSeries/Modes answer

Status invalid(const std::string& field, const std::string& rule) {
  return {StatusCode::INVALID_ARGUMENT, field + ": " + rule};
}
Status not_found(const std::string& id) {
  return {StatusCode::NOT_FOUND, "job " + id + " not found"};
}

// A Timestamp inside 0001-01-01..9999-12-31 with nanos in 0..999,999,999 (google.protobuf's
// own rule): only those convert to microseconds without overflowing int64.
bool valid_timestamp(const google::protobuf::Timestamp& t) {
  return t.seconds() >= TimeUtil::kTimestampMinSeconds &&
         t.seconds() <= TimeUtil::kTimestampMaxSeconds && t.nanos() >= 0 &&
         t.nanos() <= 999'999'999;
}

int64_t timestamp_us(const google::protobuf::Timestamp& t) {
  return TimeUtil::TimestampToMicroseconds(t);
}
void set_timestamp(int64_t us, google::protobuf::Timestamp* t) {
  *t = TimeUtil::MicrosecondsToTimestamp(us);
}

const char kBase64[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789-_";

std::string base64url_encode(const std::string& in) {
  std::string out;
  uint32_t buffer = 0;
  int bits = 0;
  for (unsigned char c : in) {
    buffer = (buffer << 8) | c;
    bits += 8;
    while (bits >= 6) {
      bits -= 6;
      out += kBase64[(buffer >> bits) & 63];
    }
  }
  if (bits > 0) out += kBase64[(buffer << (6 - bits)) & 63];
  return out;
}

bool base64url_decode(const std::string& in, std::string* out) {
  out->clear();
  uint32_t buffer = 0;
  int bits = 0;
  for (char c : in) {
    const char* p = std::strchr(kBase64, c);
    if (c == '\0' || p == nullptr) return false;
    buffer = (buffer << 6) | static_cast<uint32_t>(p - kBase64);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      *out += static_cast<char>((buffer >> bits) & 0xff);
    }
  }
  return true;
}

// Page tokens are base64url("CURSOR:FINGERPRINT"): the cursor is the handler's own position
// text, the fingerprint binds the token to the request's other fields (AIP-158: they must
// match across pages).
std::string make_page_token(const std::string& cursor, const std::string& fingerprint) {
  return base64url_encode(cursor + ":" + fingerprint);
}

// An empty token gives an empty cursor (the first page).
Status read_page_token(const std::string& page_token, const std::string& fingerprint,
                       std::string* cursor) {
  cursor->clear();
  if (page_token.empty()) return Status::OK;
  std::string token;
  const auto colon = [&] { return token.rfind(':'); };
  if (!base64url_decode(page_token, &token) || colon() == std::string::npos || colon() == 0) {
    return invalid("page_token", "not a token this server issued");
  }
  if (token.substr(colon() + 1) != fingerprint) {
    return invalid("page_token", "the filters differ from those of the first page");
  }
  *cursor = token.substr(0, colon());
  return Status::OK;
}

bool parse_seq_cursor(const std::string& cursor, int64_t* seq) {
  try {
    std::size_t used = 0;
    *seq = std::stoll(cursor, &used);
    return used == cursor.size() && *seq > 0;
  } catch (const std::exception&) {
    return false;
  }
}

Status page_size_of(int32_t requested, int* page_size) {
  if (requested < 0) return invalid("page_size", "must not be negative");
  *page_size = requested == 0 ? kDefaultPageSize : std::min<int>(requested, kMaxPageSize);
  return Status::OK;
}

// The filters a page token is bound to (AIP-158: other fields must match across pages).
std::string list_fingerprint(const v1::ListJobsRequest& req) {
  std::string f = std::to_string(req.state()) + "|" + req.label() + "|";
  if (req.has_created_after()) f += std::to_string(timestamp_us(req.created_after()));
  f += "|";
  if (req.has_created_before()) f += std::to_string(timestamp_us(req.created_before()));
  return sha256_hex(f).substr(0, 16);
}

struct FieldKind {
  bool node;
  int components;
  const char* units;
};
const std::map<std::string, FieldKind>& field_kinds() {
  static const std::map<std::string, FieldKind> kinds = {
      {"J", {false, 1, "1"}},
      {"mean_stress", {false, 1, "Pa"}},
      {"radial_stress", {false, 1, "Pa"}},
      {"hoop_stress", {false, 1, "Pa"}},
      {"von_mises", {false, 1, "Pa"}},
      {"aspect_ratio", {false, 1, "1"}},
      {"displacement", {true, 2, "m"}},
      {"velocity", {true, 2, "m/s"}},
  };
  return kinds;
}

}  // namespace

// RAII slot of the bounded pool of concurrent streams.
class StreamSlot {
 public:
  explicit StreamSlot(SimulationService& s) : s_(s) {
    acquired_ = s_.active_streams_.fetch_add(1) < s_.config_.max_streams;
  }
  ~StreamSlot() { s_.active_streams_.fetch_sub(1); }
  bool acquired() const { return acquired_; }

 private:
  SimulationService& s_;
  bool acquired_;
};

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
  google::protobuf::util::JsonParseOptions parse;
  parse.ignore_unknown_fields = true;
  if (!google::protobuf::util::JsonStringToMessage(r.spec_json, job->mutable_spec(), parse).ok()) {
    log_warning("job ", r.id, ": stored spec does not parse");
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

// "pbar = 0.5, tbar_pulse = 0.1": point i of a grid (row-major, last axis fastest).
static std::string point_coordinates(const GridPlan& plan, std::size_t index) {
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

// --- SubmitJob -----------------------------------------------------------------------------

Status SimulationService::SubmitJob(grpc::ServerContext* ctx, const v1::SubmitJobRequest* req,
                                    v1::Job* resp) {
  return guarded(auth_, ctx, "SubmitJob", [&] {
    auto hold = meshes_.hold_for_submit();  // its mesh cannot be deleted before the insert
    return submit(ctx, *req, resp);
  });
}

namespace {

// NaN stays NaN: the protobuf double carries it, and clients read it as "not known".
void fill_groups(const NondimensionalGroups& from, v1::NondimensionalGroups* g) {
  g->set_pbar(from.pbar);
  g->set_tbar_pulse(from.tbar_pulse);
  g->set_mubar(from.mubar);
  g->set_gamma(from.gamma);
  g->set_c1(from.c1);
  g->set_c2(from.c2);
  g->set_time_scale(from.time_scale_s);
}

void fill_summary(const std::string& id, const RunSummary& s, v1::JobSummary* resp) {
  resp->set_id(id);
  resp->set_elements(static_cast<int64_t>(s.elements));
  resp->set_nodes(static_cast<int64_t>(s.nodes));
  resp->set_steps(s.steps);
  resp->set_wall_time(s.wall_time_s);
  resp->set_end_time(s.end_time_s);
  fill_groups(s.groups, resp->mutable_groups());
  resp->set_energy_injected(s.energy_injected_J_per_m);
  resp->set_energy_after_pulse(s.energy_after_pulse_J_per_m);
  resp->set_max_abar_first_cycle(s.max_abar_first_cycle);
  resp->set_max_abar(s.max_abar);
  resp->set_dominant_mode_end(s.dominant_mode_end);
  resp->set_shock_at_center(s.shock_at_center_s);
  for (double t : s.rim_reflections_s) resp->add_rim_reflections(t);
  resp->set_min_dt(s.min_dt_s);
  resp->set_max_dt(s.max_dt_s);
  resp->set_kernel_time(s.kernel_time_s);
  resp->set_grind_time(s.grind_ns());
  resp->set_kernel_grind_time(s.kernel_grind_ns());
  resp->set_meshing_time(s.meshing_time_s);
  resp->set_meshing_share(s.meshing_share());
  resp->set_mesh_cache(s.mesh_cache);
  resp->set_abar_end(s.abar_end);
  resp->set_max_abar_filtered_first_cycle(s.max_abar_filtered_first_cycle);
  resp->set_max_abar_filtered(s.max_abar_filtered);
  resp->set_abar_filtered_end(s.abar_filtered_end);
  resp->set_max_aspect_ratio(s.max_aspect_ratio);
  resp->set_aspect_ratio_above_10(s.aspect_ratio_above_10_s);
}

// request_id and labels of SubmitJob and SubmitGrid.
Status check_request_id_and_labels(const std::string& request_id,
                                   const google::protobuf::Map<std::string, std::string>& labels) {
  if (request_id.size() > kMaxRequestId) {
    return invalid("request_id", "at most " + std::to_string(kMaxRequestId) + " characters");
  }
  if (labels.size() > kMaxLabels) {
    return invalid("labels", "at most " + std::to_string(kMaxLabels) + " labels");
  }
  for (const auto& [key, value] : labels) {
    if (key.empty() || key.size() > kMaxLabelKey || key.find('=') != std::string::npos) {
      return invalid("labels",
                     "keys must be 1.." + std::to_string(kMaxLabelKey) + " characters without '='");
    }
    if (value.size() > kMaxLabelValue) {
      return invalid("labels[" + key + "]",
                     "values must be at most " + std::to_string(kMaxLabelValue) + " characters");
    }
  }
  return Status::OK;
}

// INVALID_ARGUMENT for a SpecError found under `prefix` ("spec", "base_spec", or "" for grid
// fields), with the field path repeated in the trailing metadata.
Status spec_invalid(grpc::ServerContext* ctx, const std::string& prefix, const SpecError& e) {
  const std::string dot = prefix.empty() ? "" : prefix + ".";
  ctx->AddTrailingMetadata("softshock-field", dot + e.field());
  return {StatusCode::INVALID_ARGUMENT, dot + e.what()};
}

}  // namespace

Status SimulationService::submit(grpc::ServerContext* ctx, const v1::SubmitJobRequest& req,
                                 v1::Job* resp) {
  if (Status s = check_request_id_and_labels(req.request_id(), req.labels()); !s.ok()) return s;
  // A repeated request_id returns the first job, even when the queue is full (AIP-155).
  if (!req.request_id().empty()) {
    if (auto existing = catalogue_.find_by_request_id(req.request_id())) {
      fill_job(*existing, resp);
      return Status::OK;
    }
  }
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
        inserted = catalogue_.insert(job);
        break;
      } catch (const CatalogueError&) {
        if (tries >= 2 || catalogue_.get(job.id) == std::nullopt) throw;
      }
    }
  } catch (...) {
    scheduler_.release();
    throw;
  }
  if (!inserted.created) {
    scheduler_.release();  // raced with the same request_id
  } else if (job.reuse_result && runner_.reuse_identical(inserted.job)) {
    scheduler_.release();
    inserted.job = catalogue_.get(inserted.job.id).value_or(inserted.job);
  } else {
    scheduler_.enqueue(inserted.job.id, inserted.job.priority, inserted.job.seq, true);
    events_.notify(inserted.job.id);
    log_info("job ", inserted.job.id, " submitted (priority ", inserted.job.priority, ", spec ",
             inserted.job.spec_hash.substr(0, 12), ")");
  }
  fill_job(inserted.job, resp);
  return Status::OK;
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
  const std::string fingerprint = list_fingerprint(req);
  std::string cursor;
  if (Status s = read_page_token(req.page_token(), fingerprint, &cursor); !s.ok()) return s;
  if (!cursor.empty() && !parse_seq_cursor(cursor, &filter.before_seq)) {
    return invalid("page_token", "not a token this server issued");
  }
  filter.limit = page_size + 1;  // one extra row tells whether another page exists
  auto rows = catalogue_.list(filter);
  const bool more = static_cast<int>(rows.size()) > page_size;
  if (more) rows.resize(static_cast<std::size_t>(page_size));
  for (const auto& r : rows) fill_job(r, resp->add_jobs());
  if (more)
    resp->set_next_page_token(make_page_token(std::to_string(rows.back().seq), fingerprint));
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
  return guarded(auth_, ctx, "CancelJob", [&]() -> Status {
    std::string id;
    if (Status st = requested_id(*req, "jobs/", &id); !st.ok()) return st;
    return cancel(id, resp);
  });
}

Status SimulationService::cancel(const std::string& id, v1::Job* resp) {
  auto record = catalogue_.get(id);
  if (!record) return not_found(id);
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
  return guarded(auth_, ctx, "DeleteJob", [&]() -> Status {
    std::string id;
    if (Status st = requested_id(*req, "jobs/", &id); !st.ok()) return st;
    return erase(id);
  });
}

Status SimulationService::erase(const std::string& id) {
  auto record = catalogue_.get(id);
  if (!record) return not_found(id);
  if (!is_terminal(record->state)) {
    v1::Job ignored;
    if (Status s = cancel(id, &ignored); !s.ok() && s.error_code() != StatusCode::NOT_FOUND) {
      return s;
    }
    record = catalogue_.get(id);
    if (record && !is_terminal(record->state)) {
      return {StatusCode::FAILED_PRECONDITION,
              "job " + id + " is still stopping; retry DeleteJob in a few seconds"};
    }
  }
  catalogue_.erase(id);
  // Rows first, then files: a crash in between leaves an orphan folder, which the next
  // start-up removes; the other order could leave a row pointing at nothing.
  std::error_code ec;
  fs::remove_all(runner_.job_dir(id), ec);
  if (ec) log_warning("job ", id, ": removing ", runner_.job_dir(id), ": ", ec.message());
  events_.forget(id);
  log_info("job ", id, " deleted");
  return Status::OK;
}

// --- Result queries ------------------------------------------------------------------------

Status SimulationService::result_file(const std::string& id, std::string* path) const {
  auto record = catalogue_.get(id);
  if (!record) return not_found(id);
  if (!is_terminal(record->state)) {
    return {StatusCode::FAILED_PRECONDITION,
            "job " + id + " is " + to_string(record->state) + "; results exist once it finished"};
  }
  if (record->result_path.empty() || !fs::exists(record->result_path)) {
    return {StatusCode::FAILED_PRECONDITION,
            "job " + id + " is " + to_string(record->state) + " and has no result file"};
  }
  *path = record->result_path;
  return Status::OK;
}

Status SimulationService::GetJobSummary(grpc::ServerContext* ctx,
                                        const v1::GetJobSummaryRequest* req, v1::JobSummary* resp) {
  return guarded(auth_, ctx, "GetJobSummary", [&]() -> Status {
    std::string id;
    if (Status st = requested_id(*req, "jobs/", &id); !st.ok()) return st;
    return summary(id, resp);
  });
}

Status SimulationService::summary(const std::string& id, v1::JobSummary* resp) {
  auto record = catalogue_.get(id);
  if (!record) return not_found(id);
  if (!is_terminal(record->state)) {
    return {StatusCode::FAILED_PRECONDITION, "job " + id + " is " + to_string(record->state) +
                                                 "; a summary exists once it finished"};
  }
  auto stored = catalogue_.summary(id);
  if (!stored) {
    return {StatusCode::FAILED_PRECONDITION,
            "job " + id + " is " + to_string(record->state) + " and has no summary"};
  }
  fill_summary(id, stored->summary, resp);
  return Status::OK;
}

Status SimulationService::GetTimeSeries(grpc::ServerContext* ctx,
                                        const v1::GetTimeSeriesRequest* req, v1::TimeSeries* resp) {
  return guarded(auth_, ctx, "GetTimeSeries", [&] { return time_series(*req, resp); });
}

Status SimulationService::time_series(const v1::GetTimeSeriesRequest& req, v1::TimeSeries* resp) {
  std::string id, path;
  if (Status st = requested_id(req, "jobs/", &id); !st.ok()) return st;
  if (req.every() < 0) return invalid("every", "must not be negative");
  if (Status s = result_file(id, &path); !s.ok()) return s;
  ResultReader reader(path);
  const auto known = reader.series_names();
  // Each name at most once (a repeated name would be read and sent again), in request order.
  std::vector<std::string> names;
  for (const auto& n : req.names()) {
    if (std::find(known.begin(), known.end(), n) == known.end()) {
      std::string list;
      for (const auto& k : known) list += (list.empty() ? "" : ", ") + k;
      return invalid("names", "unknown series '" + n + "' (known: " + list + ")");
    }
    if (n != "time" && std::find(names.begin(), names.end(), n) == names.end()) names.push_back(n);
  }
  if (req.names().empty()) {
    for (const auto& k : known) {
      if (k != "time") names.push_back(k);
    }
  }
  // The size is known before anything is read, and only the kept samples are read.
  const std::size_t k = req.every() <= 1 ? 1 : static_cast<std::size_t>(req.every());
  const std::size_t samples = reader.dims("/timeseries/time").at(0);
  const std::size_t kept = (samples + k - 1) / k;
  if (kept * (names.size() + 1) > kMaxUnaryDoubles) {
    return {StatusCode::RESOURCE_EXHAUSTED,
            "answer too large (" + std::to_string(kept * (names.size() + 1)) + " values, at most " +
                std::to_string(kMaxUnaryDoubles) + "); ask for fewer names or a larger every"};
  }
  auto read = [&](const std::string& name) {
    ResultReader::Slice slice;
    slice.stride = k;
    slice.rows = std::min(kept, (reader.dims("/timeseries/" + name).at(0) + k - 1) / k);
    return reader.slice("/timeseries/" + name, slice);
  };
  const auto time = read("time");
  resp->mutable_time()->Add(time.begin(), time.end());
  for (const auto& n : names) {
    auto* series = resp->add_series();
    series->set_name(n);
    series->set_units(series_units(n));
    const auto values = read(n);
    series->mutable_values()->Add(values.begin(), values.end());
  }
  return Status::OK;
}

Status SimulationService::GetModes(grpc::ServerContext* ctx, const v1::GetModesRequest* req,
                                   v1::Modes* resp) {
  return guarded(auth_, ctx, "GetModes", [&] { return modes(*req, resp); });
}

Status SimulationService::modes(const v1::GetModesRequest& req, v1::Modes* resp) {
  std::string id, path;
  if (Status st = requested_id(req, "jobs/", &id); !st.ok()) return st;
  if (req.every() < 0) return invalid("every", "must not be negative");
  if (req.mode_min() < 0) return invalid("mode_min", "must not be negative");
  if (req.mode_max() < 0) return invalid("mode_max", "must not be negative");
  if (Status s = result_file(id, &path); !s.ok()) return s;
  ResultReader reader(path);
  const auto shape = reader.dims("/modes/amplitude");
  const std::size_t rows = std::min(shape.at(0), reader.dims("/modes/time").at(0));
  const std::size_t cols = shape.size() > 1 ? shape[1] : 1;
  if (cols == 0 || rows == 0) {
    resp->set_mode_min(req.mode_min());
    return Status::OK;
  }
  const int highest = static_cast<int>(cols) - 1;
  const int lo = req.mode_min();
  const int hi = req.mode_max() == 0 ? highest : req.mode_max();
  if (lo > highest) {
    return invalid("mode_min", "the result stores modes 0.." + std::to_string(highest));
  }
  if (hi > highest || hi < lo) {
    return invalid("mode_max", "must lie in mode_min.." + std::to_string(highest));
  }
  const int count = hi - lo + 1;
  const std::size_t k = req.every() <= 1 ? 1 : static_cast<std::size_t>(req.every());
  const std::size_t kept = (rows + k - 1) / k;
  if (kept * static_cast<std::size_t>(count + 1) > kMaxUnaryDoubles) {
    return {StatusCode::RESOURCE_EXHAUSTED,
            "answer too large (" + std::to_string(kept * static_cast<std::size_t>(count + 1)) +
                " values, at most " + std::to_string(kMaxUnaryDoubles) +
                "); ask for fewer modes or a larger every"};
  }
  // Only the requested rows and modes are read (never the whole dataset).
  ResultReader::Slice slice;
  slice.stride = k;
  slice.rows = kept;
  const auto times = reader.slice("/modes/time", slice);
  slice.col_first = static_cast<std::size_t>(lo);
  slice.col_count = static_cast<std::size_t>(count);
  const auto amplitudes = reader.slice("/modes/amplitude", slice);
  resp->set_mode_min(lo);
  resp->set_mode_count(count);
  resp->mutable_time()->Add(times.begin(), times.end());
  resp->mutable_amplitude()->Add(amplitudes.begin(), amplitudes.end());
  return Status::OK;
}

Status SimulationService::GetField(grpc::ServerContext* ctx, const v1::GetFieldRequest* req,
                                   grpc::ServerWriter<v1::FieldChunk>* writer) {
  return guarded(auth_, ctx, "GetField", [&]() -> Status {
    StreamSlot slot(*this);
    if (!slot.acquired()) {
      return {StatusCode::RESOURCE_EXHAUSTED,
              "too many concurrent streams (" + std::to_string(config_.max_streams) + ")"};
    }
    return field(ctx, *req, writer);
  });
}

Status SimulationService::field(grpc::ServerContext* ctx, const v1::GetFieldRequest& req,
                                grpc::ServerWriter<v1::FieldChunk>* writer) {
  std::string id, path;
  if (Status st = requested_id(req.job(), req.id(), "jobs/", &id); !st.ok()) return st;
  auto kind_it = field_kinds().find(req.name());
  if (kind_it == field_kinds().end()) {
    std::string list;
    for (const auto& [n, k] : field_kinds()) list += (list.empty() ? "" : ", ") + n;
    return invalid("name", "unknown field '" + req.name() + "' (known: " + list + ")");
  }
  const FieldKind kind = kind_it->second;
  int every = 1;
  int nx = 0, ny = 0;
  if (req.sampling_case() == v1::GetFieldRequest::kEvery) {
    if (req.every() < 0) return invalid("every", "must be >= 1");
    every = std::max(1, req.every());
  } else if (req.sampling_case() == v1::GetFieldRequest::kRaster) {
    nx = req.raster().nx();
    ny = req.raster().ny();
    if (nx < 1 || ny < 1) return invalid("raster", "nx and ny must be >= 1");
    if (nx > kMaxRasterSide || ny > kMaxRasterSide ||
        static_cast<int64_t>(nx) * ny > kMaxRasterCells) {
      return {StatusCode::RESOURCE_EXHAUSTED,
              "raster: nx, ny <= " + std::to_string(kMaxRasterSide) +
                  " and nx*ny <= " + std::to_string(kMaxRasterCells)};
    }
  }
  if (Status s = result_file(id, &path); !s.ok()) return s;
  ResultReader reader(path);
  const auto& frame_times = reader.info().frame_times;
  if (frame_times.empty()) {
    return {StatusCode::FAILED_PRECONDITION, "job " + id + " has no field frames"};
  }
  std::size_t frame = frame_times.size() - 1;
  if (req.when_case() == v1::GetFieldRequest::kFrame) {
    if (req.frame() < 0 || static_cast<std::size_t>(req.frame()) >= frame_times.size()) {
      return invalid("frame", "must lie in 0.." + std::to_string(frame_times.size() - 1));
    }
    frame = static_cast<std::size_t>(req.frame());
  } else if (req.when_case() == v1::GetFieldRequest::kTime) {
    if (!std::isfinite(req.time())) return invalid("time", "must be finite");
    frame = 0;
    for (std::size_t k = 1; k < frame_times.size(); ++k) {
      if (std::abs(frame_times[k] - req.time()) < std::abs(frame_times[frame] - req.time())) {
        frame = k;
      }
    }
  }

  v1::FieldChunk head;
  auto* header = head.mutable_header();
  header->set_name(req.name());
  header->set_frame(static_cast<int32_t>(frame));
  header->set_time(frame_times[frame]);
  header->set_components(kind.components);
  header->set_units(kind.units);
  std::vector<double> values = reader.field(frame, req.name());
  if (req.sampling_case() == v1::GetFieldRequest::kRaster) {
    const Mesh mesh = reader.mesh();
    const auto disp = req.name() == "displacement" ? values : reader.field(frame, "displacement");
    if (disp.size() != 2 * mesh.node_count()) {
      return {StatusCode::INTERNAL, "result file: displacement does not match the mesh"};
    }
    std::vector<double> x(mesh.node_count()), y(mesh.node_count());
    for (std::size_t i = 0; i < x.size(); ++i) {
      x[i] = mesh.x[i] + disp[2 * i];
      y[i] = mesh.y[i] + disp[2 * i + 1];
    }
    RasterBox box;
    try {
      values = rasterize(x, y, mesh.triangles, values, kind.components, kind.node, nx, ny, box);
    } catch (const std::length_error& e) {
      return {StatusCode::RESOURCE_EXHAUSTED, e.what()};
    }
    header->set_location("raster");
    header->set_nx(nx);
    header->set_ny(ny);
    header->set_x_min(box.x_min);
    header->set_x_max(box.x_max);
    header->set_y_min(box.y_min);
    header->set_y_max(box.y_max);
  } else {
    header->set_location(kind.node ? "node" : "element");
    header->set_every(every);
    if (every > 1) {
      const std::size_t c = static_cast<std::size_t>(kind.components);
      std::vector<double> kept;
      for (std::size_t item = 0; item * c < values.size();
           item += static_cast<std::size_t>(every)) {
        kept.insert(kept.end(), values.begin() + item * c, values.begin() + (item + 1) * c);
      }
      values.swap(kept);
    }
  }
  header->set_value_count(static_cast<int64_t>(values.size()));
  if (!writer->Write(head)) return {StatusCode::CANCELLED, "client went away"};
  for (std::size_t offset = 0; offset < values.size(); offset += kChunkDoubles) {
    if (ctx->IsCancelled()) return {StatusCode::CANCELLED, "cancelled by the client"};
    const std::size_t end = std::min(values.size(), offset + kChunkDoubles);
    v1::FieldChunk chunk;
    chunk.set_offset(static_cast<int64_t>(offset));
    chunk.mutable_values()->Add(values.begin() + offset, values.begin() + end);
    if (!writer->Write(chunk)) return {StatusCode::CANCELLED, "client went away"};
  }
  return Status::OK;
}

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
  return guarded(auth_, ctx, "SubmitGrid", [&] {
    auto hold = meshes_.hold_for_submit();
    return submit_grid(ctx, *req, resp);
  });
}

Status SimulationService::submit_grid(grpc::ServerContext* ctx, const v1::SubmitGridRequest& req,
                                      v1::Grid* resp) {
  if (Status s = check_request_id_and_labels(req.request_id(), req.labels()); !s.ok()) return s;
  if (!req.request_id().empty()) {
    if (auto existing = catalogue_.find_grid_by_request_id(req.request_id())) {
      fill_grid(*existing, resp);
      return Status::OK;
    }
  }
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
    inserted = catalogue_.insert_grid(grid, points);
  } catch (...) {
    remove_links();
    scheduler_.release(reserved);
    throw;
  }
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
    log_info("grid ", grid.id, " submitted: ", points.size(), " points, ", reused,
             " reusing identical runs");
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
    std::string cursor;
    if (Status s = read_page_token(req->page_token(), "grids", &cursor); !s.ok()) return s;
    int64_t before_seq = 0;
    if (!cursor.empty() && !parse_seq_cursor(cursor, &before_seq)) {
      return invalid("page_token", "not a token this server issued");
    }
    auto rows = catalogue_.list_grids(before_seq, page_size + 1);
    const bool more = static_cast<int>(rows.size()) > page_size;
    if (more) rows.resize(static_cast<std::size_t>(page_size));
    for (const auto& r : rows) fill_grid(r, resp->add_grids());
    if (more) resp->set_next_page_token(make_page_token(std::to_string(rows.back().seq), "grids"));
    return Status::OK;
  });
}

Status SimulationService::CancelGrid(grpc::ServerContext* ctx, const v1::CancelGridRequest* req,
                                     v1::Grid* resp) {
  return guarded(auth_, ctx, "CancelGrid", [&]() -> Status {
    std::string id;
    if (Status st = requested_id(*req, "grids/", &id); !st.ok()) return st;
    return cancel_grid(id, resp);
  });
}

Status SimulationService::cancel_grid(const std::string& id, v1::Grid* resp) {
  auto record = catalogue_.get_grid(id);
  if (!record) return grid_not_found(id);
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

// --- QueryJobs -----------------------------------------------------------------------------

Status SimulationService::QueryJobs(grpc::ServerContext* ctx, const v1::QueryJobsRequest* req,
                                    v1::QueryJobsResponse* resp) {
  return guarded(auth_, ctx, "QueryJobs", [&] { return query(*req, resp); });
}

Status SimulationService::query(const v1::QueryJobsRequest& req, v1::QueryJobsResponse* resp) {
  constexpr int kMaxFilters = 16;
  const auto& names = query_column_names();
  auto known = [&](const std::string& n) {
    return std::find(names.begin(), names.end(), n) != names.end();
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
    c.name = f.name();
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
    q.order_by = column;
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
  const bool more = static_cast<int>(rows.size()) > page_size;
  if (more) rows.resize(static_cast<std::size_t>(page_size));
  for (const auto& row : rows) {
    auto* out = resp->add_jobs();
    fill_job(row.job, out->mutable_job());
    fill_groups(row.groups, out->mutable_groups());
    if (row.summary) fill_summary(row.job.id, *row.summary, out->mutable_summary());
  }
  if (more) {
    uint64_t bits = 0;
    std::memcpy(&bits, &rows.back().sort_key, sizeof bits);
    std::ostringstream key;
    key << std::hex << bits << "," << std::dec << rows.back().job.seq;
    resp->set_next_page_token(make_page_token(key.str(), fingerprint));
  }
  return Status::OK;
}

}  // namespace softshock::server
