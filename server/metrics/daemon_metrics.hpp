// softshockd's metrics (docs/metrics.md): what the daemon counts as it runs -- job runs (queue
// wait, run time, element-steps), RPCs, mesh uploads, HTTP requests -- and what is read when
// Prometheus scrapes -- jobs by state from the catalogue, the data folder's disk. The job figures
// come from JobEvents (set_observer: on_job_event), the RPC figures from a gRPC interceptor
// (transport/rpc_metrics.hpp), the HTTP ones from the HTTP listeners (server/http/). No gRPC and
// no HTTP here, so the unit tests run fast and under the sanitizers.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <string_view>

#include "server/jobs/job_events.hpp"
#include "server/metrics/registry.hpp"
#include "server/store/catalogue.hpp"

namespace softshock::server {

// The filesystem holding the data folder, as statvfs sees it.
struct DiskSpace {
  double total_bytes = 0;
  double free_bytes = 0;  // free to the daemon (f_bavail): what the reserve is checked on
  double used_bytes = 0;  // total minus all free blocks (f_bfree)
};
// Reads the disk of `path`; false when it cannot. Tests substitute their own.
using DiskStat = std::function<bool(const std::string& path, DiskSpace* space)>;
bool statvfs_disk(const std::string& path, DiskSpace* space);

class DaemonMetrics {
 public:
  // `version` goes into softshock_build_info.
  DaemonMetrics(const Catalogue& catalogue, std::string data_dir, double min_free_bytes,
                std::string version, DiskStat disk = statvfs_disk);

  metrics::Registry& registry() { return registry_; }
  std::string render() const { return registry_.render(); }

  // The JobEvents observer. kProgress: the first progress of a run (the runner publishes one as
  // it starts) observes its queue wait and starts tracking it; later ones add the element-steps
  // done since the last. kStopped: a tracked run that is now terminal observes its run time and
  // outcome and adds the element-steps its summary has beyond those counted live (all of them for
  // a run whose progress carried no element count, as on Slurm); one that went back to the
  // queue counts as REQUEUED.
  void on_job_event(JobEventKind kind, const std::string& id, const JobProgressRecord* progress);

  // One RPC, when its status is sent (service "softshock.v1.SimulationService", method
  // "GetJob", type "unary", code "OK").
  void rpc_handled(std::string_view service, std::string_view method, std::string_view type,
                   std::string_view code, double seconds);
  // One mesh upload and the bytes it carried, stored or rejected (any status but OK).
  void mesh_upload(bool stored, std::uint64_t bytes);
  // One HTTP request on a listener ("dashboard" or "metrics"), by route pattern and status.
  void http_request(std::string_view listener, std::string_view route, int status, double seconds);

  // Runs being tracked (started under this daemon and not yet stopped).
  std::size_t tracked_runs() const;

 private:
  struct Run {
    int64_t steps_counted = 0;
    int64_t elements = 0;
  };
  void run_started(const std::string& id);
  void run_stopped(const std::string& id);

  const Catalogue& catalogue_;
  const std::string data_dir_;
  const double min_free_bytes_;
  const DiskStat disk_;
  metrics::Registry registry_;

  metrics::Family<metrics::Histogram>& queue_wait_;
  metrics::Family<metrics::Histogram>& run_time_;
  metrics::Family<metrics::Counter>& runs_finished_;
  metrics::Family<metrics::Counter>& element_steps_;
  metrics::Family<metrics::Counter>& rpcs_;
  metrics::Family<metrics::Histogram>& rpc_seconds_;
  metrics::Family<metrics::Counter>& uploads_;
  metrics::Family<metrics::Counter>& upload_bytes_;
  metrics::Family<metrics::Counter>& http_requests_;
  metrics::Family<metrics::Histogram>& http_seconds_;

  mutable std::mutex mutex_;
  std::map<std::string, Run> runs_;
};

}  // namespace softshock::server
