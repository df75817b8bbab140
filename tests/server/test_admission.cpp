// Admission control by estimate: the step estimate against the solver's own stable step, the
// daemon refusing endless, memory-hungry and disk-filling specs (jobs and grid points) with
// the figure, the limit and the driving fields, the runner's check at start, and the limits'
// settings.
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <optional>
#include <random>
#include <utility>

#include "../solver/scratch_dir.hpp"
#include "daemon_fixture.hpp"
#include "server/byte_size.hpp"
#include "server/daemon.hpp"
#include "server/daemon_config.hpp"
#include "server/jobs/admission.hpp"
#include "server/jobs/grid.hpp"
#include "server/jobs/job_extension.hpp"
#include "server/jobs/job_runner.hpp"
#include "softshock/v1/service.grpc.pb.h"
#include "solver/io/async_result_writer.hpp"
#include "solver/io/checkpoint_file.hpp"
#include "solver/resource_estimate.hpp"
#include "solver/run_spec.hpp"
#include "solver/run_summary.hpp"
#include "solver/simulation.hpp"

namespace softshock::server {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

v1::RunSpec parse(const std::string& json) {
  return normalize_spec(parse_spec_json(json));
}

// The step estimate against the steps the solver takes, from the mesh (at a job's start) and from
// the spec alone (at submission): a 4k disk to 72 ns (the load's shock crossing the disk and coming
// back) and to 400 ns. Never below, within 1.5x here (measured 1.34 / 1.36x and 1.06 / 1.08x; over
// the study's runs: docs/reliability.md, "Time steps").
TEST(ResourceEstimate, StepEstimateCoversTheStepsTaken) {
  for (const char* end : {"7.2e-8", "4e-7"}) {
    const v1::RunSpec spec =
        parse(std::string(R"({"geometry":{"target_elements":4000},"run":{"end_time":)") + end +
              R"(,"output_interval":0}})");
    const Problem problem = make_problem(spec);
    RunControl control;
    const RunResult result = run_simulation(problem, make_options(spec), control);
    ASSERT_EQ(result.status, RunStatus::kCompleted) << result.error;
    const double steps = static_cast<double>(result.steps);
    const double from_mesh = estimate_mesh_resources(spec, problem.mesh).steps;
    const double from_spec = estimate_spec_resources(spec).steps;
    std::printf(
        "to %s s: %.0f steps; estimated %.0f from the mesh (%.2fx), %.0f from the spec (%.2fx)\n",
        end, steps, from_mesh, from_mesh / steps, from_spec, from_spec / steps);
    EXPECT_GE(from_mesh, steps);
    EXPECT_LE(from_mesh, 1.5 * steps);
    EXPECT_GE(from_spec, steps);
    EXPECT_LE(from_spec, 1.5 * steps);
  }
}

// What a SUCCEEDED job leaves on the disk: its result file, and the final state the runner keeps
// for ExtendJob (job_extension.hpp; a running job's checkpoint holds the same state). Runs the
// spec to its end and prints both.
double written_bytes(const v1::RunSpec& spec, const Problem& problem, RunResult* out) {
  softshock::testing::ScratchDir dir("admission");
  AsyncResultWriter writer(dir.str(), problem.mesh, spec_to_json(spec), "test");
  RunControl control;
  control.on_frame = [&](const FieldFrame& f) { writer.write_frame(f); };
  std::optional<RunState> final_state;
  control.checkpoint_at_stop = true;
  control.on_checkpoint = [&](RunState&& state) { final_state = std::move(state); };
  *out = run_simulation(problem, make_options(spec), control);
  EXPECT_EQ(out->status, RunStatus::kCompleted) << out->error;
  writer.finish(out->history, summarize(problem, *out), true, "");
  EXPECT_TRUE(final_state && final_state->stopped);
  if (!final_state) return 0;
  save_final_state(dir.str(), spec_to_json(spec), mesh_fingerprint(problem.mesh), *final_state,
                   writer.h5_path());
  const double result = static_cast<double>(fs::file_size(writer.h5_path()));
  const double state = static_cast<double>(fs::file_size(final_state_path(dir.str())));
  std::printf("%zu elements, %zu nodes: result file %.0f bytes, kept state %.0f bytes\n",
              problem.mesh.element_count(), problem.mesh.node_count(), result, state);
  return result + state;
}

// The disk estimate against what a job actually wrote (frames every 10 ns of a 40 ns run on
// 4,000 elements): never below it -- a job must not outgrow what admission charged it -- and
// within 1.5x (the estimate rounds nodes to half the elements and counts every history column).
// With damage (model 1, to 40 ns: the state adds d and H) as without.
TEST(ResourceEstimate, DiskEstimateCoversTheWrittenResult) {
  for (const char* damage : {"", R"(,"damage":{"model":"TALAMINI","length":5e-6})"}) {
    const v1::RunSpec spec = normalize_spec(
        parse_spec_json(std::string(R"({"geometry":{"target_elements":4000},)"
                                    R"("run":{"end_time":4e-8,"output_interval":1e-8})") +
                        damage + "}"));
    const Problem problem = make_problem(spec);
    RunResult result;
    const double written = written_bytes(spec, problem, &result);
    const ResourceEstimate e = estimate_resources(
        spec, static_cast<double>(problem.mesh.element_count()), spec_area_m2(spec));
    std::printf("written %.0f bytes, disk estimate %.0f bytes (%.2fx)\n", written, e.disk_bytes,
                e.disk_bytes / written);
    EXPECT_GE(e.disk_bytes, written);
    EXPECT_LT(e.disk_bytes, 1.5 * written);
  }
}

// The same for tetrahedra (a cylinder of the default mesher, 20 um thick): the step never
// overestimated, by less than 4x; the disk estimate never below the written file, within 1.5x.
TEST(ResourceEstimate, TetrahedraStepAndDiskAreCovered) {
  const v1::RunSpec spec = normalize_spec(parse_spec_json(
      R"({"geometry":{"cylinder":{"thickness":2e-5},"target_elements":20000},
          "run":{"end_time":4e-8,"output_interval":1e-8}})"));
  const Problem problem = make_problem(spec);
  ASSERT_EQ(problem.mesh.dimension(), 3);
  RunResult result;
  const double written = written_bytes(spec, problem, &result);
  const ResourceEstimate from_spec = estimate_spec_resources(spec);
  const ResourceEstimate from_mesh = estimate_mesh_resources(spec, problem.mesh);
  const double steps = static_cast<double>(result.steps);
  std::printf(
      "3-D: %zu tetrahedra, %.0f steps; estimated %.0f from the mesh (%.2fx), %.0f from the spec "
      "(%.2fx); written %.0f bytes, disk estimate %.0f (%.2fx)\n",
      problem.mesh.element_count(), steps, from_mesh.steps, from_mesh.steps / steps,
      from_spec.steps, from_spec.steps / steps, written, from_mesh.disk_bytes,
      from_mesh.disk_bytes / written);
  // Steps: never below, within 1.5x here (measured 1.27x and 1.30x).
  EXPECT_GE(from_mesh.steps, steps);
  EXPECT_LE(from_mesh.steps, 1.5 * steps);
  EXPECT_GE(from_spec.steps, steps);
  EXPECT_LE(from_spec.steps, 1.5 * steps);
  EXPECT_GE(from_mesh.disk_bytes, written);
  EXPECT_LT(from_mesh.disk_bytes, 1.5 * written);
  // The disk from the spec (target count and nominal volume) as from the mesh, but for the
  // mesher's count (here 21,312 for 20,000: the layers are rounded to an even number; the runner
  // checks the real mesh again at start).
  const double count = static_cast<double>(problem.mesh.element_count()) / 20000;
  EXPECT_NEAR(from_spec.disk_bytes / from_mesh.disk_bytes, 1.0 / count, 0.02);
}

// Tetrahedra past the passage (the shock in, at the centre and back): the 20 um cylinder to
// 200 ns with sliding and with bonded faces, whose late steps differ (the glass holds the rim's
// corners). Never below, within 1.5x (measured 1.13 / 1.15x sliding, 1.12 / 1.14x bonded, from
// the mesh / the spec). Without the sample landing (half a step per sample) the sliding run is
// 0.94x.
TEST(ResourceEstimate, TetrahedralStepEstimateCoversSlidingAndBondedFaces) {
  for (const char* faces : {"SLIDING", "BONDED"}) {
    const v1::RunSpec spec =
        parse(std::string(R"({"geometry":{"cylinder":{"thickness":2e-5,"faces":")") + faces +
              R"("},"target_elements":20000},
            "run":{"end_time":2e-7,"output_interval":0}})");
    const Problem problem = make_problem(spec);
    const RunResult result = run_simulation(problem, make_options(spec), RunControl{});
    ASSERT_EQ(result.status, RunStatus::kCompleted) << result.error;
    const double steps = static_cast<double>(result.steps);
    const double from_mesh = estimate_mesh_resources(spec, problem.mesh).steps;
    const double from_spec = estimate_spec_resources(spec).steps;
    std::printf(
        "%s: %.0f steps; estimated %.0f from the mesh (%.2fx), %.0f from the spec (%.2fx)\n", faces,
        steps, from_mesh, from_mesh / steps, from_spec, from_spec / steps);
    EXPECT_GE(from_mesh, steps) << faces;
    EXPECT_LE(from_mesh, 1.5 * steps) << faces;
    EXPECT_GE(from_spec, steps) << faces;
    EXPECT_LE(from_spec, 1.5 * steps) << faces;
  }
}

// A bonded layer's step after the passage is set by the rim's corner held by the glass, sheared
// the more the larger the pulse's impulse p t_pulse: the 20 um layer to 400 ns with the default
// pulse (2 GPa for 8 ns) takes 1,156 steps and with half its impulse (2 GPa for 4 ns) 917. The
// estimate follows the impulse (measured 1.18 / 1.21x and 1.04 / 1.06x, from the mesh / the spec);
// the previous law, a fixed 1.37 dt_load after the passage, gave 1.51x and 1.89x.
TEST(ResourceEstimate, BondedStepEstimateFollowsTheImpulse) {
  for (const char* duration : {"8e-9", "4e-9"}) {
    const v1::RunSpec spec =
        parse(std::string(R"({"geometry":{"cylinder":{"thickness":2e-5,"faces":"BONDED"},)"
                          R"("target_elements":20000},"load":{"duration":)") +
              duration + R"(},"run":{"end_time":4e-7,"output_interval":0}})");
    const Problem problem = make_problem(spec);
    const RunResult result = run_simulation(problem, make_options(spec), RunControl{});
    ASSERT_EQ(result.status, RunStatus::kCompleted) << result.error;
    const double steps = static_cast<double>(result.steps);
    const double from_mesh = estimate_mesh_resources(spec, problem.mesh).steps;
    const double from_spec = estimate_spec_resources(spec).steps;
    std::printf(
        "pulse %s s: %.0f steps; estimated %.0f from the mesh (%.2fx), %.0f from the spec "
        "(%.2fx)\n",
        duration, steps, from_mesh, from_mesh / steps, from_spec, from_spec / steps);
    EXPECT_GE(from_mesh, steps) << duration;
    EXPECT_LE(from_mesh, 1.5 * steps) << duration;
    EXPECT_GE(from_spec, steps) << duration;
    EXPECT_LE(from_spec, 1.5 * steps) << duration;
  }
}

TEST(ResourceEstimate, ScalesAsExpected) {
  const v1::RunSpec base = parse("{}");
  const ResourceEstimate e = estimate_resources(base, 16500, spec_area_m2(base));
  std::printf("baseline: %.0f steps estimated (4,343 taken)\n", e.steps);
  // Baseline: the solver takes 4,343 steps to 800 ns (softshock-solve on examples/baseline.json);
  // the estimate never undercounts and stays within 1.5x (1.09x; 0.72x without the step's fall
  // after the passage, 0.996x without the sample landing); ~50 MB result (docs/deploy.md), ~85 MB
  // peak.
  EXPECT_GE(e.steps, 4343);
  EXPECT_LE(e.steps, 1.5 * 4343);
  EXPECT_GT(e.disk_bytes, 20e6);
  EXPECT_LT(e.disk_bytes, 80e6);
  EXPECT_GT(e.memory_bytes, 70e6);
  EXPECT_LT(e.memory_bytes, 200e6);
  // Four times the elements in the same area: steps double (acoustic limit, dt ~ h) to quadruple
  // (viscous limit, dt ~ h^2).
  const ResourceEstimate fine = estimate_resources(base, 4 * 16500, spec_area_m2(base));
  EXPECT_GE(fine.steps / e.steps, 2.0);
  EXPECT_LE(fine.steps / e.steps, 4.0);
}

class AdmissionService : public testing::DaemonFixture {
 protected:
  AdmissionService() : DaemonFixture("admission") {}
  void SetUp() override { start(); }

  grpc::Status submit(const std::string& spec_json, std::string* field = nullptr) {
    v1::SubmitJobRequest req;
    *req.mutable_spec() = parse_spec_json(spec_json);
    grpc::ClientContext ctx;
    ctx.set_deadline(std::chrono::system_clock::now() + 10s);
    v1::Job job;
    const grpc::Status s = stub_->SubmitJob(&ctx, req, &job);
    if (field) {
      const auto it = ctx.GetServerTrailingMetadata().find("softshock-field");
      *field = it == ctx.GetServerTrailingMetadata().end()
                   ? ""
                   : std::string(it->second.data(), it->second.size());
    }
    if (s.ok()) {  // do not leave it running
      v1::DeleteJobRequest del;
      del.set_id(job.id());
      grpc::ClientContext c2;
      v1::DeleteJobResponse r;
      stub_->DeleteJob(&c2, del, &r);
    }
    return s;
  }
};

TEST_F(AdmissionService, RefusesEndlessHungryAndHugeSpecsNamingFigureLimitAndFields) {
  std::string field;
  // The issue's endless job: ~1e10 steps.
  grpc::Status s =
      submit(R"({"geometry":{"disk":{"radius":1e-12}},"run":{"end_time":1e-8}})", &field);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(field, "spec.run.end_time");
  for (const char* part :
       {"time steps", "max-steps = 1e+07", "geometry.target_elements", "load.pressure"}) {
    EXPECT_NE(s.error_message().find(part), std::string::npos) << part << ": " << s.error_message();
  }
  // 1e6 history samples x 1025 values: ~16 GiB.
  s = submit(R"({"geometry":{"target_elements":20},"run":{"modes":1024,"history_interval":8e-13}})",
             &field);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(field, "spec.run.history_interval");
  EXPECT_NE(s.error_message().find("max-job-memory = 4 GiB"), std::string::npos)
      << s.error_message();
  // 1961 frames of 2M elements: ~220 GB.
  s = submit(R"({"geometry":{"target_elements":2000000},
                 "run":{"end_time":1e-5,"output_interval":5.1e-9}})",
             &field);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(field, "spec.run.output_interval");
  EXPECT_NE(s.error_message().find("max-job-disk = 16 GiB"), std::string::npos)
      << field << s.error_message();
  // The baseline passes.
  EXPECT_TRUE(submit("{}").ok());
}

TEST_F(AdmissionService, EveryGridPointIsChecked) {
  v1::SubmitGridRequest req;
  *req.mutable_base_spec() = parse_spec_json(R"({"run":{"end_time":1e-8}})");
  auto* axis = req.add_axes();
  axis->set_name("geometry.disk.radius");
  axis->add_values(90e-6);
  axis->add_values(1e-12);
  grpc::ClientContext ctx;
  ctx.set_deadline(std::chrono::system_clock::now() + 10s);
  v1::Grid grid;
  const grpc::Status s = stub_->SubmitGrid(&ctx, req, &grid);
  EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(s.error_message().rfind("axes: the point geometry.disk.radius = 1e-12 is refused: "
                                    "spec.run.end_time: the run needs about",
                                    0),
            0u)
      << s.error_message();
}

// One job run by a JobRunner with `rc` (data_dir filled in); returns its final record.
JobRecord run_one(RunnerConfig rc, const std::string& spec_json) {
  const fs::path dir =
      fs::temp_directory_path() / ("softshock-limits-" + std::to_string(std::random_device{}()));
  fs::create_directories(dir / "jobs");
  JobRecord out;
  {
    Catalogue catalogue((dir / "catalogue.sqlite").string());
    JobEvents events;
    rc.data_dir = dir.string();
    JobRunner runner(rc, catalogue, events);
    const CanonicalSpec spec = canonical_spec(parse_spec_json(spec_json), {});
    NewJob job;
    job.id = "j";
    job.spec_json = spec.json;
    job.spec_hash = spec.hash;
    job.create_us = now_us();
    catalogue.insert(job);
    CancelToken token;
    runner.run("j", token);
    out = catalogue.get("j").value();
  }
  fs::remove_all(dir);
  return out;
}

constexpr const char* kTiny = R"({"geometry":{"target_elements":200},"run":{"end_time":5e-9}})";

TEST(JobLimits, LimitsLoweredSinceSubmissionFailTheJobAtStart) {
  RunnerConfig rc;
  rc.admission.max_steps = 1;
  const JobRecord done = run_one(rc, kTiny);
  EXPECT_EQ(done.state, JobState::kFailed);
  EXPECT_EQ(done.reason, reason::kInvalidSpec);
  EXPECT_NE(done.error.find("max-steps = 1:"), std::string::npos) << done.error;
}

TEST(JobLimits, ARunPastItsWallLimitFailsWallTimeExceeded) {
  RunnerConfig rc;
  rc.max_wall_time_s = 0.05;  // checked with each progress publication (every 0.1 s)
  const JobRecord done = run_one(
      rc, R"({"geometry":{"target_elements":4000},"run":{"end_time":1e-5,"output_interval":0}})");
  EXPECT_EQ(done.state, JobState::kFailed);
  EXPECT_EQ(done.reason, "WALL_TIME_EXCEEDED");
  EXPECT_NE(done.error.find("wall time limit"), std::string::npos) << done.error;
}

// Every byte count in the daemon's messages (admission, the disk's reserve, checkpoints, mesh
// quotas and limits) in one format: binary units, as the limits are set, three figures.
TEST(ByteSize, BinaryUnitsToThreeSignificantFigures) {
  EXPECT_EQ(byte_size(512), "512 B");
  EXPECT_EQ(byte_size(20.3 * 1024), "20.3 KiB");
  EXPECT_EQ(byte_size(100e6), "95.4 MiB");
  EXPECT_EQ(byte_size(256.0 * (1 << 20)), "256 MiB");
  EXPECT_EQ(byte_size(1023.4 * (1 << 20)), "1023 MiB");  // no exponent
  EXPECT_EQ(byte_size(16.0 * (1ull << 30)), "16 GiB");
  EXPECT_EQ(byte_size(1.5 * (1ull << 40)), "1.5 TiB");
}

TEST(JobLimits, AJobDoesNotStartWithoutRoomForItsResult) {
  RunnerConfig rc;
  rc.free_bytes = [](const std::string&) { return 100e6; };  // below the 256 MiB reserve
  const JobRecord done = run_one(rc, kTiny);
  EXPECT_EQ(done.state, JobState::kFailed);
  EXPECT_EQ(done.reason, "DISK_FULL");
  EXPECT_NE(done.error.find("95.4 MiB free"), std::string::npos) << done.error;
}

TEST(JobLimits, AJobStopsBeforeAFrameWouldEatIntoTheReserve) {
  RunnerConfig rc;
  int calls = 0;
  // Room at start, none once frames come (another job filled the disk meanwhile).
  rc.free_bytes = [&calls](const std::string&) { return ++calls == 1 ? 1e12 : 1e6; };
  const JobRecord done = run_one(rc, kTiny);
  EXPECT_EQ(done.state, JobState::kFailed) << "recorded: the catalogue stays writable";
  EXPECT_EQ(done.reason, "DISK_FULL");
  EXPECT_NE(done.error.find("below the reserve"), std::string::npos) << done.error;
  EXPECT_EQ(calls, 2) << "no frame was written after the first refusal";
}

TEST(AdmissionSettings, LimitsComeFromTheSettingsTable) {
  auto load = [](std::vector<std::string> args) {
    return load_daemon_config(args, [](const char*) -> const char* { return nullptr; }).config;
  };
  const DaemonConfig d = load({});
  EXPECT_EQ(d.max_steps, 1e7);
  EXPECT_EQ(d.max_job_memory_bytes, 4.0 * (1ull << 30));
  EXPECT_EQ(d.max_job_disk_bytes, 16.0 * (1ull << 30));
  EXPECT_EQ(d.max_wall_time_s, 21600) << "a default wall limit: no job runs forever";
  const DaemonConfig c =
      load({"--max-steps", "5000", "--max-job-memory", "512M", "--max-job-disk=2GiB"});
  EXPECT_EQ(c.max_steps, 5000);
  EXPECT_EQ(c.max_job_memory_bytes, 512.0 * (1 << 20));
  EXPECT_EQ(c.max_job_disk_bytes, 2.0 * (1ull << 30));
  for (const char* bad : {"12X", "0", "-1G", "G", ""}) {
    EXPECT_THROW(load({"--max-job-memory", bad}), ConfigError) << bad;
  }
}

}  // namespace
}  // namespace softshock::server
