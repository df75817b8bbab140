// The fuzz target: what a client controls, fed to the daemon's own code. The first byte picks
// the path, the rest is the client's payload:
//   0..5  spec JSON  -> parse -> defaults + canonical floats + validation -> canonical hash ->
//         groups -> admission estimate (the SubmitJob pipeline, without storing anything)
//   6     SubmitGridRequest JSON -> base spec pipeline -> grid expansion -> every point's
//         admission (grids over 256 points are skipped: each point is a full spec pipeline)
//   7..11 a serialized GetTimeSeries / GetModes / ListJobs / QueryJobs / GetGridReduction
//         request, answered by the real SimulationService against a real finished job
//   12    an uploaded mesh file (MSH bytes), through the daemon's MeshStore: staged, hashed,
//         checked by the confined softshock-mesh child and stored or refused (the driver's
//         --meshes mode feeds only this path; each execution starts a child)
// Expected refusals (SpecError, a non-OK status) are fine; anything else escaping, or any
// sanitizer report, is a finding. The entry point has libFuzzer's signature, so the same file
// also links with clang's -fsanitize=fuzzer (docs/reliability.md).
#include <google/protobuf/stubs/logging.h>
#include <google/protobuf/util/json_util.h>
#include <grpcpp/server_context.h>

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <memory>
#include <random>
#include <string>
#include <string_view>

#include "server/jobs/admission.hpp"
#include "server/jobs/executor.hpp"
#include "server/jobs/grid.hpp"
#include "server/jobs/job_events.hpp"
#include "server/jobs/job_runner.hpp"
#include "server/jobs/mesh_process.hpp"
#include "server/store/catalogue.hpp"
#include "server/store/mesh_store.hpp"
#include "server/transport/auth.hpp"
#include "server/transport/simulation_service.hpp"
#include "solver/resource_estimate.hpp"
#include "solver/run_spec.hpp"

namespace softshock::server {
namespace {

namespace fs = std::filesystem;

// A data folder with one SUCCEEDED job (a 200-element, 5 ns run with 8 modes), and the service
// over it. The executor is never started: nothing the fuzzer does runs a job.
struct Fixture {
  fs::path dir;
  std::unique_ptr<Catalogue> catalogue;
  JobEvents events;
  std::unique_ptr<JobRunner> runner;
  std::unique_ptr<LocalExecutor> executor;
  Authenticator auth;  // no users: authentication off, every call the default admin
  std::unique_ptr<MeshStore> meshes;
  std::unique_ptr<SimulationService> service;
  std::string job_id = "fuzzjob";
  SpecLimits limits;
  AdmissionLimits admission;

  Fixture() {
    google::protobuf::SetLogHandler(nullptr);  // invalid UTF-8 in a string field is expected
    dir = fs::temp_directory_path() / ("softshock-fuzz-" + std::to_string(std::random_device{}()));
    fs::create_directories(dir / "jobs");
    fs::create_directories(dir / "meshes");
    catalogue = std::make_unique<Catalogue>((dir / "catalogue.sqlite").string());
    RunnerConfig rc;
    rc.data_dir = dir.string();
    runner = std::make_unique<JobRunner>(rc, *catalogue, events);
    limits = runner->limits();
    const CanonicalSpec spec = canonical_spec(
        parse_spec_json(R"({"geometry":{"target_elements":200},"run":{"end_time":5e-9,
                            "output_interval":2.5e-9,"history_interval":2e-10,"modes":8}})"),
        limits);
    NewJob job;
    job.id = job_id;
    job.spec_json = spec.json;
    job.spec_hash = spec.hash;
    job.create_us = now_us();
    catalogue->insert(job);
    CancelToken token;
    runner->run(job_id, token);
    if (catalogue->get(job_id)->state != JobState::kSucceeded) {
      std::cerr << "fuzz fixture: the reference job did not succeed\n";
      std::abort();
    }
    executor = std::make_unique<LocalExecutor>(Scheduler::Options{1, 10},
                                               [](const std::string&, CancelToken&) {});
    ServiceConfig sc;
    sc.limits = limits;
    MeshStoreLimits mesh_limits;
    mesh_limits.max_bytes = 1 << 20;
    mesh_limits.max_elements = limits.max_elements;
    meshes = std::make_unique<MeshStore>(runner->meshes_dir(), mesh_limits,
                                         mesh_validator_in_child(find_mesher(), {}));
    service = std::make_unique<SimulationService>(sc, *catalogue, *executor, events, *runner, auth,
                                                  *meshes);
  }
  ~Fixture() {
    service.reset();
    meshes.reset();
    executor.reset();
    runner.reset();
    catalogue.reset();
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

Fixture& fixture() {
  static Fixture f;
  return f;
}

// How deep executions got, for the driver's report: parsed (a spec or a request), valid (a
// spec that passed validation, or a request answered OK).
long long g_parsed = 0, g_valid = 0;

void spec_pipeline(const v1::RunSpec& parsed, Fixture& f) {
  ++g_parsed;
  try {
    const CanonicalSpec c = canonical_spec(parsed, f.limits);
    ++g_valid;
    check_spec_admission(c.spec, f.admission);
    (void)spec_groups(c.spec);
    // The stored form reads back to the same hash (what the runner and reuse rely on).
    const CanonicalSpec again = canonical_spec(parse_stored_spec(c.json), f.limits);
    if (again.hash != c.hash) {
      std::cerr << "canonical spec is not stable: " << c.json << "\n";
      std::abort();
    }
  } catch (const SpecError&) {
  }
}

void grid_pipeline(const std::string& json, Fixture& f) {
  v1::SubmitGridRequest req;
  if (!google::protobuf::util::JsonStringToMessage(json, &req).ok()) return;
  ++g_parsed;
  int64_t points = 1;
  for (const auto& axis : req.axes()) {
    const int64_t n = axis.values_size() + (axis.has_linspace() ? axis.linspace().num() : 0) +
                      (axis.has_geomspace() ? axis.geomspace().num() : 0);
    points *= std::max<int64_t>(1, std::min<int64_t>(n, 100000));
    if (points > 256) return;
  }
  try {
    const CanonicalSpec base = canonical_spec(req.base_spec(), f.limits);
    const GridPlan plan = expand_grid(base.spec, req.axes(), f.limits);
    ++g_valid;
    for (const auto& p : plan.points) check_spec_admission(p.spec, f.admission);
  } catch (const SpecError&) {
  }
}

// Half the time the request names the real job, so the handlers get past the lookup.
template <typename Request>
bool parse_request(const std::string& bytes, Request* req, Fixture& f) {
  if (!req->ParseFromString(bytes)) return false;
  if (req->id().empty() || (bytes.size() % 2) == 0) req->set_id(f.job_id);
  ++g_parsed;
  return true;
}

template <typename Request>
bool parse_plain(const std::string& bytes, Request* req) {
  if (!req->ParseFromString(bytes)) return false;
  ++g_parsed;
  return true;
}

void count(const grpc::Status& s) {
  if (s.ok()) ++g_valid;
}

// Mesh uploads by outcome (the driver's report): stored, refused as unusable, of those the ones
// whose checker crashed (a crash that would have been the daemon's with Gmsh in process).
long long g_meshes_stored = 0, g_meshes_refused = 0, g_checker_crashes = 0;

void mesh_upload(const std::string& bytes, Fixture& f) {
  ++g_parsed;
  try {
    const v1::Mesh m = f.meshes->add(bytes, "fuzz.msh", 0);
    ++g_valid, ++g_meshes_stored;
    f.meshes->remove(m.id());  // keeps the folder small; the next identical input stores again
  } catch (const SpecError& e) {
    ++g_meshes_refused;
    if (std::string_view(e.what()).find("Gmsh crashed reading it") != std::string_view::npos ||
        std::string_view(e.what()).find("ran out of its limits") != std::string_view::npos) {
      ++g_checker_crashes;
    }
  }
}

}  // namespace
}  // namespace softshock::server

extern "C" void softshock_fuzz_depth(long long* parsed, long long* valid) {
  *parsed = softshock::server::g_parsed;
  *valid = softshock::server::g_valid;
}

extern "C" void softshock_fuzz_mesh_outcomes(long long* stored, long long* refused,
                                             long long* checker_crashes) {
  *stored = softshock::server::g_meshes_stored;
  *refused = softshock::server::g_meshes_refused;
  *checker_crashes = softshock::server::g_checker_crashes;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace softshock;
  using namespace softshock::server;
  if (size < 1) return 0;
  Fixture& f = fixture();
  const std::string payload(reinterpret_cast<const char*>(data + 1), size - 1);
  grpc::ServerContext ctx;
  switch (data[0] % 13) {
    case 12:
      mesh_upload(payload, f);
      break;
    case 6:
      grid_pipeline(payload, f);
      break;
    case 7: {
      v1::GetTimeSeriesRequest req;
      v1::TimeSeries resp;
      if (parse_request(payload, &req, f)) count(f.service->GetTimeSeries(&ctx, &req, &resp));
      break;
    }
    case 8: {
      v1::GetModesRequest req;
      v1::Modes resp;
      if (parse_request(payload, &req, f)) count(f.service->GetModes(&ctx, &req, &resp));
      break;
    }
    case 9: {
      v1::ListJobsRequest req;
      v1::ListJobsResponse resp;
      if (parse_plain(payload, &req)) count(f.service->ListJobs(&ctx, &req, &resp));
      break;
    }
    case 10: {
      v1::QueryJobsRequest req;
      v1::QueryJobsResponse resp;
      if (parse_plain(payload, &req)) count(f.service->QueryJobs(&ctx, &req, &resp));
      break;
    }
    case 11: {
      v1::GetGridReductionRequest req;
      v1::GridReduction resp;
      if (parse_plain(payload, &req)) count(f.service->GetGridReduction(&ctx, &req, &resp));
      break;
    }
    default: {
      v1::RunSpec spec;
      try {
        spec = parse_spec_json(payload);
      } catch (const SpecError&) {
        return 0;
      }
      spec_pipeline(spec, f);
    }
  }
  return 0;
}
