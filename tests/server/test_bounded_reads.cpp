// Result RPCs read only what they answer: GetTimeSeries sends each name once and reads the
// kept samples only, GetModes reads the requested rows and modes only; and the number of calls
// served at once is capped (RESOURCE_EXHAUSTED beyond).
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <random>
#include <thread>

#include "daemon_fixture.hpp"
#include "server/daemon.hpp"
#include "softshock/v1/service.grpc.pb.h"
#include "solver/io/result_file.hpp"

namespace softshock::server {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

class BoundedReads : public testing::DaemonFixture {
 protected:
  BoundedReads() : DaemonFixture("bounded") {}

  void start(int max_concurrent_rpcs = 256) {
    DaemonConfig c = config();
    c.max_concurrent_rpcs = max_concurrent_rpcs;
    DaemonFixture::start(c);
  }

  v1::Job submit(const v1::RunSpec& spec) {
    v1::SubmitJobRequest req;
    *req.mutable_spec() = spec;
    v1::Job job;
    const grpc::Status s = stub_->SubmitJob(ctx().get(), req, &job);
    EXPECT_TRUE(s.ok()) << s.error_message();
    return job;
  }
};

TEST_F(BoundedReads, SeriesAndModesAreSlicesOfTheStoredData) {
  start();
  v1::RunSpec spec;
  spec.mutable_geometry()->set_target_elements(200);
  spec.mutable_run()->set_end_time(5e-9);
  spec.mutable_run()->set_history_interval(1e-10);  // ~50 samples
  spec.mutable_run()->set_modes(8);
  const v1::Job job = wait_terminal(submit(spec).id());
  ASSERT_EQ(job.state(), v1::SUCCEEDED) << job.error();
  ResultReader file((dir_ / "data" / job.result_path()).string());

  v1::GetTimeSeriesRequest sreq;
  sreq.set_id(job.id());
  for (const char* n : {"abar", "abar", "kinetic_energy", "abar", "time"}) sreq.add_names(n);
  sreq.set_every(3);
  v1::TimeSeries series;
  ASSERT_TRUE(stub_->GetTimeSeries(ctx().get(), sreq, &series).ok());
  ASSERT_EQ(series.series_size(), 2) << "each name once";
  EXPECT_EQ(series.series(0).name(), "abar");
  EXPECT_EQ(series.series(1).name(), "kinetic_energy");
  const auto time = file.series("time");
  const auto abar = file.series("abar");
  ASSERT_GT(time.size(), 20u);
  ASSERT_EQ(static_cast<std::size_t>(series.time_size()), (time.size() + 2) / 3);
  for (int i = 0; i < series.time_size(); ++i) {
    EXPECT_EQ(series.time(i), time[3 * i]);
    EXPECT_EQ(series.series(0).values(i), abar[3 * i]);
  }

  v1::GetModesRequest mreq;
  mreq.set_id(job.id());
  mreq.set_mode_min(2);
  mreq.set_mode_max(5);
  mreq.set_every(2);
  v1::Modes modes;
  ASSERT_TRUE(stub_->GetModes(ctx().get(), mreq, &modes).ok());
  std::size_t rows = 0, cols = 0;
  const auto all = file.mode_amplitudes(rows, cols);
  const auto mode_times = file.mode_times();
  ASSERT_EQ(cols, 9u);
  ASSERT_EQ(modes.mode_count(), 4);
  ASSERT_EQ(static_cast<std::size_t>(modes.time_size()), (rows + 1) / 2);
  ASSERT_EQ(modes.amplitude_size(), modes.time_size() * 4);
  for (int r = 0; r < modes.time_size(); ++r) {
    EXPECT_EQ(modes.time(r), mode_times[2 * r]);
    for (int m = 0; m < 4; ++m) {
      EXPECT_EQ(modes.amplitude(r * 4 + m), all[2 * r * cols + 2 + m]) << r << " " << m;
    }
  }
}

TEST_F(BoundedReads, CallsBeyondTheCapAreResourceExhausted) {
  start(4);
  // Streams on a job that stays QUEUED behind a long run each hold one of the server's
  // threads until cancelled.
  v1::RunSpec long_run;
  long_run.mutable_geometry()->set_target_elements(4000);
  long_run.mutable_run()->set_end_time(1e-5);
  long_run.mutable_run()->set_output_interval(0);
  submit(long_run);
  const v1::Job waiting = submit(long_run);
  std::vector<std::unique_ptr<grpc::ClientContext>> contexts;
  std::vector<std::unique_ptr<grpc::ClientReader<v1::Job>>> streams;
  grpc::StatusCode refused = grpc::StatusCode::OK;
  for (int i = 0; i < 16 && refused == grpc::StatusCode::OK; ++i) {
    contexts.push_back(ctx());
    v1::WatchJobRequest w;
    w.set_id(waiting.id());
    streams.push_back(stub_->WatchJob(contexts.back().get(), w));
    v1::Job first;
    if (!streams.back()->Read(&first)) refused = streams.back()->Finish().error_code();
  }
  EXPECT_EQ(refused, grpc::StatusCode::RESOURCE_EXHAUSTED)
      << "16 streams open with a cap of 4 calls";
  for (auto& c : contexts) c->TryCancel();
  for (std::size_t i = 0; i + 1 < streams.size(); ++i) streams[i]->Finish();
}

}  // namespace
}  // namespace softshock::server
