#include "server/simulation_service.hpp"

#include <google/protobuf/util/json_util.h>
#include <google/protobuf/util/time_util.h>
#include <grpcpp/grpcpp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <map>
#include <thread>

#include "server/field_raster.hpp"
#include "server/log.hpp"
#include "server/spec_hash.hpp"
#include "solver/io/result_file.hpp"

namespace softshock::server {

namespace fs = std::filesystem;
using google::protobuf::util::TimeUtil;
using grpc::Status;
using grpc::StatusCode;

namespace {

constexpr int kDefaultPageSize = 50;
constexpr int kMaxPageSize = 1000;
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

// "jobs/{id}" or the bare id; ids are [A-Za-z0-9_-]{1,64} (they name folders on disk).
bool parse_id(const std::string& name, std::string* id) {
  std::string s = name.rfind("jobs/", 0) == 0 ? name.substr(5) : name;
  if (s.empty() || s.size() > 64) return false;
  for (unsigned char c : s) {
    if (!std::isalnum(c) && c != '-' && c != '_') return false;
  }
  *id = std::move(s);
  return true;
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

// The filters a page token is bound to (AIP-158: other fields must match across pages).
std::string list_fingerprint(const v1::ListJobsRequest& req) {
  std::string f = std::to_string(req.state()) + "|" + req.label() + "|";
  if (req.has_created_after()) f += std::to_string(timestamp_us(req.created_after()));
  f += "|";
  if (req.has_created_before()) f += std::to_string(timestamp_us(req.created_before()));
  return sha256_hex(f).substr(0, 16);
}

const std::map<std::string, std::string>& series_units() {
  static const std::map<std::string, std::string> units = {
      {"time", "s"},
      {"kinetic_energy", "J/m"},
      {"elastic_energy", "J/m"},
      {"dissipated_energy", "J/m"},
      {"external_work", "J/m"},
      {"abar", "1"},
      {"center_mean_stress", "Pa"},
      {"rim_mean_radial_displacement", "m"},
      {"rim_mean_radial_velocity", "m/s"},
      {"rim_mean_radial_acceleration", "m/s^2"},
      {"rim_min_hoop_stress", "Pa"},
      {"dt", "s"},
  };
  return units;
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
      {"displacement", {true, 2, "m"}},
      {"velocity", {true, 2, "m/s"}},
  };
  return kinds;
}

template <typename T>
std::vector<T> every_kth(const std::vector<T>& v, int k) {
  if (k <= 1) return v;
  std::vector<T> out;
  out.reserve(v.size() / static_cast<std::size_t>(k) + 1);
  for (std::size_t i = 0; i < v.size(); i += static_cast<std::size_t>(k)) out.push_back(v[i]);
  return out;
}

// Runs a handler behind the token check; any exception becomes INTERNAL (and a log line) so a
// bug in one request never takes the daemon down.
template <typename F>
Status guarded(const Authenticator& auth, const grpc::ServerContext* ctx, const char* rpc,
               F&& body) {
  if (Status s = auth.check(*ctx); !s.ok()) return s;
  try {
    return body();
  } catch (const CatalogueError& e) {
    log_error(rpc, ": catalogue: ", e.what());
    return {StatusCode::UNAVAILABLE, std::string("catalogue: ") + e.what()};
  } catch (const std::exception& e) {
    log_error(rpc, ": ", e.what());
    return {StatusCode::INTERNAL, e.what()};
  }
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
                                     Scheduler& scheduler, JobEvents& events,
                                     const JobRunner& runner, const Authenticator& auth)
    : config_(config),
      catalogue_(catalogue),
      scheduler_(scheduler),
      events_(events),
      runner_(runner),
      auth_(auth),
      id_random_(std::random_device{}()) {}

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
  job->set_error(r.error);
  job->set_reason(r.reason);
  job->set_result_path(r.result_path);
  job->set_attempt(r.attempt);
  job->set_request_id(r.request_id);
  job->set_spec_hash(r.spec_hash);
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
  return guarded(auth_, ctx, "SubmitJob", [&] { return submit(ctx, *req, resp); });
}

Status SimulationService::submit(grpc::ServerContext* ctx, const v1::SubmitJobRequest& req,
                                 v1::Job* resp) {
  if (req.request_id().size() > kMaxRequestId) {
    return invalid("request_id", "at most " + std::to_string(kMaxRequestId) + " characters");
  }
  if (req.labels_size() > static_cast<int>(kMaxLabels)) {
    return invalid("labels", "at most " + std::to_string(kMaxLabels) + " labels");
  }
  for (const auto& [key, value] : req.labels()) {
    if (key.empty() || key.size() > kMaxLabelKey || key.find('=') != std::string::npos) {
      return invalid("labels",
                     "keys must be 1.." + std::to_string(kMaxLabelKey) + " characters without '='");
    }
    if (value.size() > kMaxLabelValue) {
      return invalid("labels[" + key + "]",
                     "values must be at most " + std::to_string(kMaxLabelValue) + " characters");
    }
  }
  // A repeated request_id returns the first job, even when the queue is full (AIP-155).
  if (!req.request_id().empty()) {
    if (auto existing = catalogue_.find_by_request_id(req.request_id())) {
      fill_job(*existing, resp);
      return Status::OK;
    }
  }
  v1::RunSpec spec;
  try {
    spec = normalize_spec(req.spec(), config_.limits);
    check_mesh_file(spec);
  } catch (const SpecError& e) {
    ctx->AddTrailingMetadata("softshock-field", "spec." + e.field());
    return {StatusCode::INVALID_ARGUMENT, std::string("spec.") + e.what()};
  }
  NewJob job;
  job.spec_json = spec_to_json(spec);
  job.spec_hash = sha256_hex(job.spec_json);
  job.request_id = req.request_id();
  job.labels.insert(req.labels().begin(), req.labels().end());
  job.priority = req.priority();

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
    if (!parse_id(req->id(), &id)) return invalid("id", "not a job name");
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
  if (req.page_size() < 0) return invalid("page_size", "must not be negative");
  const int page_size =
      req.page_size() == 0 ? kDefaultPageSize : std::min(req.page_size(), kMaxPageSize);
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
  if (!req.page_token().empty()) {
    std::string token;
    const auto colon = [&] { return token.find(':'); };
    if (!base64url_decode(req.page_token(), &token) || colon() == std::string::npos) {
      return invalid("page_token", "not a token this server issued");
    }
    if (token.substr(colon() + 1) != fingerprint) {
      return invalid("page_token", "the filters differ from those of the first page");
    }
    try {
      filter.before_seq = std::stoll(token.substr(0, colon()));
    } catch (const std::exception&) {
      return invalid("page_token", "not a token this server issued");
    }
    if (filter.before_seq <= 0) return invalid("page_token", "not a token this server issued");
  }
  filter.limit = page_size + 1;  // one extra row tells whether another page exists
  auto rows = catalogue_.list(filter);
  const bool more = static_cast<int>(rows.size()) > page_size;
  if (more) rows.resize(static_cast<std::size_t>(page_size));
  for (const auto& r : rows) fill_job(r, resp->add_jobs());
  if (more) {
    resp->set_next_page_token(
        base64url_encode(std::to_string(rows.back().seq) + ":" + fingerprint));
  }
  return Status::OK;
}

// --- WatchJob ------------------------------------------------------------------------------

Status SimulationService::WatchJob(grpc::ServerContext* ctx, const v1::WatchJobRequest* req,
                                   grpc::ServerWriter<v1::Job>* writer) {
  return guarded(auth_, ctx, "WatchJob", [&]() -> Status {
    std::string id;
    if (!parse_id(req->id(), &id)) return invalid("id", "not a job name");
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
    if (!parse_id(req->id(), &id)) return invalid("id", "not a job name");
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
    // Running (or a worker just picked it up): the solver checks the flag every step.
    scheduler_.cancel(id, StopReason::kUser);
    record = wait_terminal(id, config_.cancel_wait_s);
    if (!record) return not_found(id);
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
    if (!parse_id(req->id(), &id)) return invalid("id", "not a job name");
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
    if (!parse_id(req->id(), &id)) return invalid("id", "not a job name");
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
  const RunSummary& s = stored->summary;
  resp->set_id(id);
  resp->set_elements(static_cast<int64_t>(s.elements));
  resp->set_nodes(static_cast<int64_t>(s.nodes));
  resp->set_steps(s.steps);
  resp->set_wall_time(s.wall_time_s);
  resp->set_end_time(s.end_time_s);
  auto* g = resp->mutable_groups();
  g->set_pbar(s.groups.pbar);
  g->set_tbar_pulse(s.groups.tbar_pulse);
  g->set_mubar(s.groups.mubar);
  g->set_gamma(s.groups.gamma);
  g->set_c1(s.groups.c1);
  g->set_c2(s.groups.c2);
  g->set_time_scale(s.groups.time_scale_s);
  resp->set_energy_injected(s.energy_injected_J_per_m);
  resp->set_energy_after_pulse(s.energy_after_pulse_J_per_m);
  resp->set_max_abar_first_cycle(s.max_abar_first_cycle);
  resp->set_max_abar(s.max_abar);
  resp->set_dominant_mode_end(s.dominant_mode_end);
  resp->set_shock_at_center(s.shock_at_center_s);
  for (double t : s.rim_reflections_s) resp->add_rim_reflections(t);
  resp->set_min_dt(s.min_dt_s);
  resp->set_max_dt(s.max_dt_s);
  return Status::OK;
}

Status SimulationService::GetTimeSeries(grpc::ServerContext* ctx,
                                        const v1::GetTimeSeriesRequest* req, v1::TimeSeries* resp) {
  return guarded(auth_, ctx, "GetTimeSeries", [&] { return time_series(*req, resp); });
}

Status SimulationService::time_series(const v1::GetTimeSeriesRequest& req, v1::TimeSeries* resp) {
  std::string id, path;
  if (!parse_id(req.id(), &id)) return invalid("id", "not a job name");
  if (req.every() < 0) return invalid("every", "must not be negative");
  if (Status s = result_file(id, &path); !s.ok()) return s;
  ResultReader reader(path);
  const auto known = reader.series_names();
  std::vector<std::string> names;
  for (const auto& n : req.names()) {
    if (std::find(known.begin(), known.end(), n) == known.end()) {
      std::string list;
      for (const auto& k : known) list += (list.empty() ? "" : ", ") + k;
      return invalid("names", "unknown series '" + n + "' (known: " + list + ")");
    }
    names.push_back(n);
  }
  if (names.empty()) {
    for (const auto& k : known) {
      if (k != "time") names.push_back(k);
    }
  }
  const auto time = every_kth(reader.series("time"), req.every());
  if (time.size() * (names.size() + 1) > kMaxUnaryDoubles) {
    return {StatusCode::RESOURCE_EXHAUSTED, "answer too large (" +
                                                std::to_string(time.size() * (names.size() + 1)) +
                                                " values); ask for fewer names or a larger every"};
  }
  resp->mutable_time()->Add(time.begin(), time.end());
  for (const auto& n : names) {
    if (n == "time") continue;
    auto* series = resp->add_series();
    series->set_name(n);
    auto u = series_units().find(n);
    series->set_units(u == series_units().end() ? "" : u->second);
    const auto values = every_kth(reader.series(n), req.every());
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
  if (!parse_id(req.id(), &id)) return invalid("id", "not a job name");
  if (req.every() < 0) return invalid("every", "must not be negative");
  if (req.mode_min() < 0) return invalid("mode_min", "must not be negative");
  if (req.mode_max() < 0) return invalid("mode_max", "must not be negative");
  if (Status s = result_file(id, &path); !s.ok()) return s;
  ResultReader reader(path);
  std::size_t rows = 0, cols = 0;
  const auto amplitudes = reader.mode_amplitudes(rows, cols);
  const auto times = reader.mode_times();
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
  const std::size_t kept = (std::min(rows, times.size()) + k - 1) / k;
  if (kept * static_cast<std::size_t>(count + 1) > kMaxUnaryDoubles) {
    return {StatusCode::RESOURCE_EXHAUSTED,
            "answer too large; ask for fewer modes or a larger every"};
  }
  resp->set_mode_min(lo);
  resp->set_mode_count(count);
  for (std::size_t r = 0; r < std::min(rows, times.size()); r += k) {
    resp->add_time(times[r]);
    const double* row = amplitudes.data() + r * cols;
    resp->mutable_amplitude()->Add(row + lo, row + hi + 1);
  }
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
  if (!parse_id(req.id(), &id)) return invalid("id", "not a job name");
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
    values = rasterize(x, y, mesh.triangles, values, kind.components, kind.node, nx, ny, box);
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

}  // namespace softshock::server
