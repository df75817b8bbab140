// softshock.v1.SimulationService over the catalogue, scheduler and result files (API and
// errors: docs/api.md). Handlers are synchronous; the long ones (WatchJob, GetField) hold a
// slot of a bounded pool of concurrent streams and honour ServerContext::IsCancelled().
#pragma once

#include <atomic>
#include <mutex>
#include <random>
#include <string>

#include "server/jobs/admission.hpp"
#include "server/jobs/executor.hpp"
#include "server/jobs/job_events.hpp"
#include "server/jobs/job_runner.hpp"
#include "server/jobs/scheduler.hpp"
#include "server/policy/audit.hpp"
#include "server/policy/quotas.hpp"
#include "server/store/catalogue.hpp"
#include "server/store/file_digests.hpp"
#include "server/store/mesh_store.hpp"
#include "server/transport/auth.hpp"
#include "softshock/v1/service.grpc.pb.h"
#include "solver/io/result_file.hpp"
#include "solver/run_spec.hpp"

namespace softshock::server {

struct ServiceConfig {
  SpecLimits limits;
  AdmissionLimits admission;          // estimated steps, memory, disk per job
  int max_streams = 64;               // concurrent WatchJob + GetField streams
  double watch_min_interval_s = 0.2;  // at most ~5 WatchJob updates per second
  double cancel_wait_s = 5.0;         // CancelJob/DeleteJob wait this long for a running job
  QuotaLimits quotas;                 // max_queued_per_user (the mesh bounds are the store's)
};

class SimulationService final : public v1::SimulationService::Service {
 public:
  SimulationService(ServiceConfig config, Catalogue& catalogue, Executor& scheduler,
                    JobEvents& events, const JobRunner& runner, const Authenticator& auth,
                    const MeshStore& meshes);

  grpc::Status SubmitJob(grpc::ServerContext* ctx, const v1::SubmitJobRequest* req,
                         v1::Job* resp) override;
  grpc::Status GetJob(grpc::ServerContext* ctx, const v1::GetJobRequest* req,
                      v1::Job* resp) override;
  grpc::Status ExtendJob(grpc::ServerContext* ctx, const v1::ExtendJobRequest* req,
                         v1::Job* resp) override;
  grpc::Status ListJobs(grpc::ServerContext* ctx, const v1::ListJobsRequest* req,
                        v1::ListJobsResponse* resp) override;
  grpc::Status WatchJob(grpc::ServerContext* ctx, const v1::WatchJobRequest* req,
                        grpc::ServerWriter<v1::Job>* writer) override;
  grpc::Status CancelJob(grpc::ServerContext* ctx, const v1::CancelJobRequest* req,
                         v1::Job* resp) override;
  grpc::Status DeleteJob(grpc::ServerContext* ctx, const v1::DeleteJobRequest* req,
                         v1::DeleteJobResponse* resp) override;
  grpc::Status GetJobSummary(grpc::ServerContext* ctx, const v1::GetJobSummaryRequest* req,
                             v1::JobSummary* resp) override;
  grpc::Status GetTimeSeries(grpc::ServerContext* ctx, const v1::GetTimeSeriesRequest* req,
                             v1::TimeSeries* resp) override;
  grpc::Status GetModes(grpc::ServerContext* ctx, const v1::GetModesRequest* req,
                        v1::Modes* resp) override;
  grpc::Status GetField(grpc::ServerContext* ctx, const v1::GetFieldRequest* req,
                        grpc::ServerWriter<v1::FieldChunk>* writer) override;
  grpc::Status SubmitGrid(grpc::ServerContext* ctx, const v1::SubmitGridRequest* req,
                          v1::Grid* resp) override;
  grpc::Status GetGrid(grpc::ServerContext* ctx, const v1::GetGridRequest* req,
                       v1::Grid* resp) override;
  grpc::Status ListGrids(grpc::ServerContext* ctx, const v1::ListGridsRequest* req,
                         v1::ListGridsResponse* resp) override;
  grpc::Status CancelGrid(grpc::ServerContext* ctx, const v1::CancelGridRequest* req,
                          v1::Grid* resp) override;
  grpc::Status GetGridReduction(grpc::ServerContext* ctx, const v1::GetGridReductionRequest* req,
                                v1::GridReduction* resp) override;
  grpc::Status QueryJobs(grpc::ServerContext* ctx, const v1::QueryJobsRequest* req,
                         v1::QueryJobsResponse* resp) override;
  grpc::Status GetCaller(grpc::ServerContext* ctx, const v1::GetCallerRequest* req,
                         v1::Caller* resp) override;
  grpc::Status ListSummaryFigures(grpc::ServerContext* ctx,
                                  const v1::ListSummaryFiguresRequest* req,
                                  v1::SummaryFigures* resp) override;
  // simulation_service_downloads.cpp
  grpc::Status DownloadResult(grpc::ServerContext* ctx, const v1::DownloadResultRequest* req,
                              grpc::ServerWriter<v1::DownloadChunk>* writer) override;
  // simulation_service_labels.cpp
  grpc::Status UpdateJobLabels(grpc::ServerContext* ctx, const v1::UpdateJobLabelsRequest* req,
                               v1::Job* resp) override;

  int active_streams() const { return active_streams_.load(); }

 private:
  friend class StreamSlot;
  // parent_id: ExtendJob's, the job the new one continues.
  grpc::Status submit(grpc::ServerContext* ctx, const Caller& caller,
                      const v1::SubmitJobRequest& req, v1::Job* resp, AuditRecord& audit,
                      const std::string& parent_id = {});
  grpc::Status list(const v1::ListJobsRequest& req, v1::ListJobsResponse* resp);
  grpc::Status watch(grpc::ServerContext* ctx, const std::string& id,
                     grpc::ServerWriter<v1::Job>* writer);
  // Cancel and delete check the owner first (policy/ownership.hpp).
  grpc::Status cancel(const Caller& caller, const std::string& id, v1::Job* resp);
  grpc::Status erase(const Caller& caller, const std::string& id);
  grpc::Status summary(const std::string& id, v1::JobSummary* resp);
  grpc::Status time_series(const v1::GetTimeSeriesRequest& req, v1::TimeSeries* resp);
  grpc::Status modes(const v1::GetModesRequest& req, v1::Modes* resp);
  grpc::Status field(grpc::ServerContext* ctx, const v1::GetFieldRequest& req,
                     grpc::ServerWriter<v1::FieldChunk>* writer);
  // A 3-D result's raster (a planar slice) or decimated surface, into values and the header.
  grpc::Status field_3d(const v1::GetFieldRequest& req, const ResultReader& reader,
                        std::size_t frame, int components, bool node_field, int nx, int ny,
                        std::size_t max_triangles, std::vector<double>& values,
                        v1::FieldHeader* header) const;
  grpc::Status submit_grid(grpc::ServerContext* ctx, const Caller& caller,
                           const v1::SubmitGridRequest& req, v1::Grid* resp, AuditRecord& audit);
  grpc::Status cancel_grid(const Caller& caller, const std::string& id, v1::Grid* resp);
  grpc::Status grid_reduction(const v1::GetGridReductionRequest& req, v1::GridReduction* resp);
  grpc::Status query(const v1::QueryJobsRequest& req, v1::QueryJobsResponse* resp);
  grpc::Status download(grpc::ServerContext* ctx, const v1::DownloadResultRequest& req,
                        grpc::ServerWriter<v1::DownloadChunk>* writer);
  // The grid with its live counts, progress and derived state.
  void fill_grid(const GridRecord& record, v1::Grid* grid) const;

  // `text` with every "DATA_DIR/" replaced (absolute server paths never leave the daemon).
  std::string without_data_dir(const std::string& text, const std::string& replacement) const;
  // Job state with the live progress of a running job overlaid.
  void fill_job(const JobRecord& record, v1::Job* job) const;
  // Waits until the job is terminal (or gone) or the wait runs out; returns the last record.
  std::optional<JobRecord> wait_terminal(const std::string& id, double seconds) const;
  // The result file of a job whose results can be queried, or a FAILED_PRECONDITION.
  grpc::Status result_file(const std::string& id, std::string* path) const;
  std::string new_job_id();

  ServiceConfig config_;
  Catalogue& catalogue_;
  Executor& scheduler_;  // local or slurm (server/executor.hpp)
  JobEvents& events_;
  const JobRunner& runner_;
  const Authenticator& auth_;
  const MeshStore& meshes_;  // uploaded meshes, and where spec mesh files resolve
  FileDigests digests_;      // SHA-256 of result files already downloaded (DownloadResult)
  std::atomic<int> active_streams_{0};
  std::mutex id_mutex_;
  std::mt19937_64 id_random_;
};

}  // namespace softshock::server
