// softshockd as an object: data folder, catalogue, start-up recovery, scheduler, job runner and
// the gRPC server, started and stopped in the right order. main() reads the configuration
// (server/daemon_config.hpp: flags, environment, file) and handles signals; tests can run a
// Daemon in-process.
#pragma once

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "server/policy/quotas.hpp"

namespace softshock::server {

struct DaemonConfig {
  std::string data_dir = "./data";
  std::string listen = "127.0.0.1:50051";
  std::string port_file;  // empty = none
  int workers = 0;        // 0 = hardware threads
  std::size_t max_queued = 1000;
  // Who may call (server/policy/users.hpp): the token file's token is one user, `token_user`,
  // an admin; the users file has one `user:token[:role]` line per user. Both empty = no
  // authentication (every call is the default user, an admin).
  std::string token_file;
  std::string token_user = "default";
  std::string users_file;
  bool insecure_no_auth = false;  // allow no token on a non-loopback listen address
  std::string tls_cert, tls_key;  // both or neither
  // HTTP (server/http/, docs/api.md "HTTP: dashboard and metrics"): the dashboard and its JSON
  // API, behind the same token and TLS as gRPC (empty = off); /metrics in the Prometheus text
  // format without a token (empty = off). Port files as port_file.
  std::string http_listen, http_port_file;
  std::string metrics_listen, metrics_port_file;
  int max_elements = 2'000'000;
  double max_end_time_s = 1e-5;
  double max_wall_time_s = 21600;  // 6 h; 0 = none
  // Wall time between a running job's checkpoints (server/jobs/job_checkpoint.hpp); 0 = none.
  double checkpoint_interval_s = 600;
  // Admission by estimate (server/admission.hpp): steps, peak memory and result size per job.
  double max_steps = 10'000'000;
  double max_job_memory_bytes = 4.0 * (1ull << 30);
  double max_job_disk_bytes = 16.0 * (1ull << 30);
  int solver_threads = 1;
  long long mesh_cache_bytes = 1LL << 30;  // DATA/cache/meshes, LRU by bytes; 0 = no cache
  int max_attempts = 3;
  // Free space the data folder keeps (jobs start, frames are written, uploads and submissions
  // are taken only above it).
  double min_free_bytes = 256.0 * (1 << 20);
  // Per-user and global bounds on queued jobs and stored meshes (server/policy/quotas.hpp).
  QuotaLimits quotas;
  int max_streams = 64;
  // Calls served at once (gRPC resource quota: one thread each in the synchronous server);
  // a call beyond gets RESOURCE_EXHAUSTED instead of another thread.
  int max_concurrent_rpcs = 256;
  int max_receive_bytes = 4 << 20;
  double rpc_drain_s = 2.0;  // shutdown: in-flight RPCs get this long
  double job_stop_s = 6.0;   // shutdown: running jobs get this long to stop and requeue
  // Where jobs run (docs/cluster.md): "local" (in-process workers) or "slurm" (sbatch; then
  // `workers` is the most tasks of one array job running at once).
  std::string executor = "local";
  std::string slurm_partition, slurm_account;    // empty = the cluster's default
  std::string slurm_time_limit;                  // sbatch --time; empty = the partition's
  std::string slurm_shared_dir;                  // seen by daemon and nodes; empty = DATA/slurm
  std::vector<std::string> slurm_sbatch_args;    // extra sbatch options, verbatim
  std::string slurm_solver = "softshock-solve";  // the solver on the compute nodes
  double slurm_poll_s = 1.0;                     // how often Slurm is asked for job states
};

class Daemon {
 public:
  // Prepares the data folder (exclusive lock, catalogue, recovery). Throws std::exception
  // with a message fit for the user on any problem.
  explicit Daemon(DaemonConfig config);
  ~Daemon();
  Daemon(const Daemon&) = delete;
  Daemon& operator=(const Daemon&) = delete;

  // Starts listening and the workers; writes the port file. Throws if it cannot listen.
  void start();
  int port() const;
  int http_port() const;     // 0 = no dashboard
  int metrics_port() const;  // 0 = no metrics listener
  // Orderly stop: stop accepting, end streams, requeue running jobs. Returns false if some
  // job did not stop within job_stop_s (it was recorded as QUEUED anyway; the caller should
  // exit the process promptly, without running destructors that wait for it).
  bool stop();
  // Reads the token and users files again (SIGHUP) and swaps the users in for calls that start
  // afterwards. Throws std::exception with a message fit for the log (the old users stay).
  void reload_users();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace softshock::server
