#include "server/daemon.hpp"

#include <fcntl.h>
#include <google/protobuf/stubs/logging.h>
#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>
#include <sys/file.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "grpc/health/v1/health.pb.h"
#include "server/byte_size.hpp"
#include "server/daemon_config.hpp"
#include "server/http/http_frontend.hpp"
#include "server/jobs/job_events.hpp"
#include "server/jobs/job_runner.hpp"
#include "server/jobs/mesh_process.hpp"
#include "server/jobs/scheduler.hpp"
#include "server/jobs/slurm_executor.hpp"
#include "server/log.hpp"
#include "server/metrics/daemon_metrics.hpp"
#include "server/policy/users.hpp"
#include "server/store/catalogue.hpp"
#include "server/transport/auth.hpp"
#include "server/transport/health_warnings.hpp"
#include "server/transport/mesh_service.hpp"
#include "server/transport/rpc_metrics.hpp"
#include "server/transport/simulation_service.hpp"
#include "softshock/version.hpp"

namespace softshock::server {

namespace fs = std::filesystem;

namespace {

// Largest mesh a client may upload (streamed to disk as it arrives): 64 MiB is an ASCII .msh of
// roughly 800,000 triangles; the thesis's meshes are under 2 MB.
constexpr int64_t kMaxMeshUploadBytes = 64ll << 20;

std::string read_file(const std::string& path, const char* what) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(std::string("cannot read ") + what + " " + path);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// What the protobuf library logs -- a request with invalid UTF-8 in a string field, say: a client
// can make it log at will, so it goes through a rate limit (and our log's format). Unauthenticated
// calls never get this far (transport/auth.hpp).
void protobuf_log(google::protobuf::LogLevel level, const char* file, int line,
                  const std::string& message) {
  static LogRateLimit limit(20, 1);
  const LogLevel ours = level >= google::protobuf::LOGLEVEL_ERROR     ? LogLevel::kError
                        : level == google::protobuf::LOGLEVEL_WARNING ? LogLevel::kWarning
                                                                      : LogLevel::kInfo;
  log_limited(limit, ours,
              "protobuf " + log_field(file, 80) + ":" + std::to_string(line) + ": " +
                  std::string(message.substr(0, 300)));
}

// tmp + rename: a test polling the file never reads a partial number.
void write_port_file(const std::string& path, int port) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::trunc);
    out << port << "\n";
    if (!out) throw std::runtime_error("cannot write port file " + tmp);
  }
  fs::rename(tmp, path);
}

}  // namespace

struct Daemon::Impl {
  DaemonConfig config;
  int lock_fd = -1;
  std::unique_ptr<Catalogue> catalogue;
  // server/metrics/: after the catalogue it reads, before everything that reports to it (job
  // events, the runner, the gRPC server's interceptor), so it outlives them all.
  std::unique_ptr<DaemonMetrics> metrics;
  JobEvents events;
  std::unique_ptr<JobRunner> runner;
  std::unique_ptr<Authenticator> auth;
  std::unique_ptr<Executor> scheduler;  // local or slurm
  std::unique_ptr<MeshStore> meshes;
  std::unique_ptr<SimulationService> service;
  std::unique_ptr<MeshService> mesh_service;
  std::unique_ptr<grpc::Server> server;
  int port = 0;
  std::unique_ptr<HttpFrontend> http;  // server/http/: the dashboard and /metrics
  bool stopped = false;
  // What the start-up log warns about the set-up; health answers repeat it.
  std::vector<std::string> setup_warnings;

  ~Impl() {
    if (lock_fd >= 0) ::close(lock_fd);
  }

  void lock_data_dir() {
    const std::string path = (fs::path(config.data_dir) / "softshockd.lock").string();
    lock_fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (lock_fd < 0) throw std::runtime_error("cannot open " + path);
    // flock is released by the kernel when the process dies, even by kill -9.
    if (::flock(lock_fd, LOCK_EX | LOCK_NB) != 0) {
      throw std::runtime_error("another softshockd is using " + config.data_dir);
    }
  }

  void recover() {
    const RecoveryReport report = catalogue->recover(config.max_attempts, now_us());
    for (const auto& id : report.requeued) {
      log_warning("job ", id, " was RUNNING when the daemon stopped: requeued (INTERRUPTED)");
    }
    for (const auto& id : report.failed) {
      log_warning("job ", id, " was RUNNING when the daemon stopped: FAILED (MAX_ATTEMPTS)");
    }
    // Leftovers: temporary result files of interrupted runs, folders of deleted jobs.
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(fs::path(config.data_dir) / "jobs", ec)) {
      if (!entry.is_directory()) continue;
      const std::string id = entry.path().filename().string();
      if (!catalogue->get(id)) {
        log_info("removing ", entry.path().string(), " (no such job in the catalogue)");
        fs::remove_all(entry.path(), ec);
      } else {
        runner->remove_stale_files(id);
      }
    }
  }
};

Daemon::Daemon(DaemonConfig config) : impl_(std::make_unique<Impl>()) {
  Impl& d = *impl_;
  if (config.workers <= 0) config.workers = std::max(1u, std::thread::hardware_concurrency());
  if (config.max_attempts < 1) throw std::invalid_argument("--max-attempts must be >= 1");
  if (config.solver_threads < 1) throw std::invalid_argument("--solver-threads must be >= 1");
  if (config.max_queued < 1) throw std::invalid_argument("--max-queued must be >= 1");
  if (config.tls_cert.empty() != config.tls_key.empty()) {
    throw std::invalid_argument("--tls-cert and --tls-key go together");
  }
  // Also here, not only in the loader: an embedding program must not expose an open daemon.
  if (auto problem = exposure_problem(config)) throw std::invalid_argument(*problem);
  if (auto warning = transport_warning(config)) {
    log_warning(*warning);
    d.setup_warnings.push_back(*warning);
  }
  fs::create_directories(config.data_dir);
  config.data_dir = fs::canonical(config.data_dir).string();
  fs::create_directories(fs::path(config.data_dir) / "jobs");
  fs::create_directories(fs::path(config.data_dir) / "meshes");
  d.config = config;
  d.lock_data_dir();

  d.auth = std::make_unique<Authenticator>(
      load_users(config.token_file, config.token_user, config.users_file));

  d.catalogue =
      std::make_unique<Catalogue>((fs::path(config.data_dir) / "catalogue.sqlite").string());
  d.metrics = std::make_unique<DaemonMetrics>(*d.catalogue, config.data_dir, config.min_free_bytes,
                                              SOFTSHOCK_VERSION);
  d.events.set_observer([m = d.metrics.get()](JobEventKind kind, const std::string& id,
                                              const JobProgressRecord* progress) {
    m->on_job_event(kind, id, progress);
  });

  RunnerConfig rc;
  rc.data_dir = config.data_dir;
  rc.limits.max_elements = config.max_elements;
  rc.limits.max_end_time_s = config.max_end_time_s;
  rc.solver_threads = config.solver_threads;
  rc.max_wall_time_s = config.max_wall_time_s;
  rc.checkpoint_interval_s = config.checkpoint_interval_s;
  rc.mesh_cache_bytes = static_cast<std::uint64_t>(config.mesh_cache_bytes);
  rc.admission.max_steps = config.max_steps;
  rc.admission.max_memory_bytes = config.max_job_memory_bytes;
  rc.admission.max_disk_bytes = config.max_job_disk_bytes;
  rc.min_free_bytes = config.min_free_bytes;
  rc.mesher = find_mesher();
  if (rc.mesher.empty()) {
    d.setup_warnings.push_back(
        "softshock-mesh is not installed beside softshockd: mesh uploads are refused (they are "
        "checked in it)" +
        std::string(config.executor == "local"
                        ? ", and Gmsh meshing runs in the daemon, where a cancel or the wall-time "
                          "limit waits until it ends"
                        : ""));
    log_warning(d.setup_warnings.back());
  }
  d.runner = std::make_unique<JobRunner>(rc, *d.catalogue, d.events);
  d.recover();

  if (config.executor == "slurm") {
    SlurmConfig slurm;
    slurm.shared_dir = config.slurm_shared_dir.empty()
                           ? (fs::path(config.data_dir) / "slurm").string()
                           : fs::absolute(config.slurm_shared_dir).string();
    slurm.partition = config.slurm_partition;
    slurm.account = config.slurm_account;
    slurm.time_limit = config.slurm_time_limit;
    slurm.sbatch_args = config.slurm_sbatch_args;
    slurm.solver = config.slurm_solver;
    slurm.solver_threads = config.solver_threads;
    slurm.max_elements = config.max_elements;
    slurm.max_end_time_s = config.max_end_time_s;
    slurm.max_wall_time_s = config.max_wall_time_s;
    slurm.checkpoint_interval_s = config.checkpoint_interval_s;
    slurm.array_throttle = config.workers;
    slurm.poll_s = config.slurm_poll_s;
    slurm.max_queued = config.max_queued;
    d.scheduler = std::make_unique<SlurmExecutor>(slurm, *d.catalogue, *d.runner, d.events);
  } else if (config.executor == "local") {
    if (!d.catalogue->submitted_jobs().empty()) {
      log_warning(
          "jobs submitted to Slurm by an earlier run are not watched by the local "
          "executor; start with --executor slurm to finish them");
    }
    d.scheduler = std::make_unique<LocalExecutor>(
        Scheduler::Options{config.workers, config.max_queued},
        [runner = d.runner.get()](const std::string& id, CancelToken& cancel) {
          runner->run(id, cancel);
        });
  } else {
    throw std::invalid_argument("--executor must be local or slurm, not '" + config.executor + "'");
  }
  // Queued jobs in catalogue order; the bound does not apply to what was already accepted.
  const auto queued = d.catalogue->queued_jobs();
  for (const auto& q : queued) {
    // Already on Slurm: only the slurm executor may touch it (no second run).
    if (config.executor != "slurm" && !d.catalogue->slurm_job_id(q.id).empty()) continue;
    d.scheduler->enqueue(q.id, q.priority, q.seq, false);
  }

  ServiceConfig sc;
  sc.limits = rc.limits;
  sc.admission = rc.admission;
  sc.max_streams = config.max_streams;
  sc.quotas = config.quotas;
  MeshStoreLimits store_limits;
  store_limits.max_bytes = kMaxMeshUploadBytes;
  store_limits.max_elements = rc.limits.max_elements;
  store_limits.min_free_bytes = config.min_free_bytes;
  store_limits.quotas = config.quotas;
  d.meshes = std::make_unique<MeshStore>(d.runner->meshes_dir(), store_limits,
                                         mesh_validator_in_child(rc.mesher, MeshCheckLimits{}));
  d.service = std::make_unique<SimulationService>(sc, *d.catalogue, *d.scheduler, d.events,
                                                  *d.runner, *d.auth, *d.meshes);
  d.mesh_service = std::make_unique<MeshService>(*d.meshes, *d.catalogue, *d.auth);
  add_service_gauges(*d.metrics, *d.scheduler, *d.service, *d.auth, config.workers);

  std::ostringstream counts;
  for (const auto& [state, n] : d.catalogue->counts())
    counts << " " << to_string(state) << "=" << n;
  log_info(
      "softshockd ", SOFTSHOCK_VERSION, " data-dir=", config.data_dir, " listen=", config.listen,
      " workers=", config.workers, " max-queued=", config.max_queued,
      " solver-threads=", config.solver_threads, " max-elements=", config.max_elements,
      " max-end-time=", config.max_end_time_s, " max-wall-time=", config.max_wall_time_s,
      " checkpoint-interval=", config.checkpoint_interval_s, " max-attempts=", config.max_attempts,
      " executor=", config.executor, " auth=", d.auth->enabled() ? "bearer-token" : "none",
      " users=", d.auth->user_count(), " tls=", config.tls_cert.empty() ? "off" : "on",
      " catalogue-schema=", d.catalogue->schema_version());
  log_info("catalogue:", counts.str().empty() ? " empty" : counts.str(), "; ", queued.size(),
           " job(s) queued");
  if (!d.catalogue->room_held()) {
    log_warning("the disk lacks ", byte_size(kCatalogueRoomBytes),
                " for the catalogue's reserved room; deletions on a full disk may fail "
                "until space is freed");
  }
}

void Daemon::reload_users() {
  Impl& d = *impl_;
  d.auth->replace(load_users(d.config.token_file, d.config.token_user, d.config.users_file));
  log_info("users reloaded: ", d.auth->user_count(), " user(s)");
}

Daemon::~Daemon() {
  if (impl_ && !impl_->stopped) stop();
}

void Daemon::start() {
  Impl& d = *impl_;
  grpc::EnableDefaultHealthCheckService(true);
  // The built-in health service has no protobuf descriptors; touching the generated ones links
  // health.proto into the descriptor pool, so reflection can describe grpc.health.v1.Health.
  (void)grpc::health::v1::HealthCheckRequest::descriptor();
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  google::protobuf::SetLogHandler(&protobuf_log);
  // The token check runs in gRPC's auth filter, before a call reaches a handler (auth.hpp).
  std::shared_ptr<grpc::ServerCredentials> creds =
      d.config.tls_cert.empty()
          ? d.auth->credentials()
          : d.auth->credentials(read_file(d.config.tls_key, "TLS key"),
                                read_file(d.config.tls_cert, "TLS certificate"));
  grpc::ServerBuilder builder;
  // gRPC sets SO_REUSEPORT by default, which lets a second daemon bind the same port and
  // silently share its traffic; a busy port must be an error instead.
  builder.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
  builder.AddListeningPort(d.config.listen, creds, &d.port);
  builder.RegisterService(d.service.get());
  builder.RegisterService(d.mesh_service.get());
  {
    std::vector<std::unique_ptr<grpc::experimental::ServerInterceptorFactoryInterface>> creators;
    creators.push_back(rpc_metrics(*d.metrics));
    if (!d.setup_warnings.empty()) creators.push_back(health_warnings(d.setup_warnings));
    builder.experimental().SetInterceptorCreators(std::move(creators));
  }
  builder.SetMaxReceiveMessageSize(d.config.max_receive_bytes);
  // Bounded threads, so a flood of calls cannot grow the daemon without limit: a call that
  // finds every thread busy is answered RESOURCE_EXHAUSTED by gRPC.
  grpc::ResourceQuota quota("softshockd-rpcs");
  quota.SetMaxThreads(std::max(4, d.config.max_concurrent_rpcs));
  builder.SetResourceQuota(quota);
  d.server = builder.BuildAndStart();
  if (!d.server || d.port == 0) {
    throw std::runtime_error("cannot listen on " + d.config.listen);
  }
  if (!d.config.http_listen.empty() || !d.config.metrics_listen.empty()) {
    // The dashboard's API calls this server's own services in-process (server/http/).
    grpc::ChannelArguments args;
    args.SetMaxReceiveMessageSize(16 << 20);
    d.http = std::make_unique<HttpFrontend>(
        HttpFrontendConfig{d.config.http_listen, d.config.metrics_listen, d.config.tls_cert,
                           d.config.tls_key},
        *d.metrics);
    d.http->start(d.server->InProcessChannel(args));
    if (d.http->dashboard_port() != 0) {
      log_info("dashboard on ", d.http->dashboard_tls() ? "https" : "http", "://",
               d.config.http_listen, " (port ", d.http->dashboard_port(), ")");
      if (!d.config.http_port_file.empty()) {
        write_port_file(d.config.http_port_file, d.http->dashboard_port());
      }
    }
    if (d.http->metrics_port() != 0) {
      log_info("metrics on http://", d.config.metrics_listen, "/metrics (port ",
               d.http->metrics_port(), ")");
      if (!d.config.metrics_port_file.empty()) {
        write_port_file(d.config.metrics_port_file, d.http->metrics_port());
      }
    }
  }
  d.scheduler->start();
  if (!d.config.port_file.empty()) write_port_file(d.config.port_file, d.port);
  log_info("listening on ", d.config.listen, " (port ", d.port, ")");
}

int Daemon::port() const {
  return impl_->port;
}

int Daemon::http_port() const {
  return impl_->http ? impl_->http->dashboard_port() : 0;
}

int Daemon::metrics_port() const {
  return impl_->http ? impl_->http->metrics_port() : 0;
}

bool Daemon::stop() {
  Impl& d = *impl_;
  if (d.stopped) return true;
  d.stopped = true;
  using namespace std::chrono;
  log_info("stopping: no new calls; running jobs go back to the queue");
  if (d.server) {
    if (auto* health = d.server->GetHealthCheckService()) health->SetServingStatus(false);
  }
  if (d.http) d.http->stop();  // its requests are calls of the server below: first
  d.events.shutdown();         // ends WatchJob streams and waits in CancelJob
  if (d.server) {
    d.server->Shutdown(system_clock::now() + duration_cast<system_clock::duration>(
                                                 duration<double>(d.config.rpc_drain_s)));
    d.server->Wait();
  }
  const auto stuck =
      d.scheduler->shutdown(duration_cast<milliseconds>(duration<double>(d.config.job_stop_s)));
  for (const auto& id : stuck) {
    // Still inside an uninterruptible phase (e.g. meshing): record it as QUEUED ourselves; the
    // worker's own later transition is conditional on RUNNING and becomes a no-op.
    if (auto job = d.catalogue->get(id); job && job->state == JobState::kRunning) {
      d.catalogue->requeue(id, job->attempt, reason::kShutdown, now_us());
    }
    log_warning("job ", id, " did not stop in time; recorded as QUEUED");
  }
  log_info("stopped");
  return stuck.empty();
}

}  // namespace softshock::server
