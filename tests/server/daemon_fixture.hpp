// A softshockd running inside the test process, for the tests that talk to a real daemon over
// gRPC: a fresh scratch folder (the data folder is DIR/data), loopback on a port the OS chose,
// one worker unless told otherwise, and a SimulationService stub. Stopped and removed with the
// fixture.
#pragma once

#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <thread>

#include "server/daemon.hpp"
#include "softshock/v1/service.grpc.pb.h"

namespace softshock::server::testing {

class DaemonFixture : public ::testing::Test {
 protected:
  // The scratch folder is named after `prefix` and a random number (tests run in parallel).
  explicit DaemonFixture(const std::string& prefix)
      : dir_(std::filesystem::temp_directory_path() /
             ("softshock-" + prefix + "-" + std::to_string(std::random_device{}()))) {}
  void TearDown() override {
    stub_.reset();
    if (daemon_) daemon_->stop();
    daemon_.reset();
    std::filesystem::remove_all(dir_);
  }

  // The daemon's settings before start(): data folder, loopback listen and one worker filled
  // in; a test changes what it needs.
  static DaemonConfig config() {
    DaemonConfig c;
    c.listen = "127.0.0.1:0";
    c.workers = 1;
    return c;
  }
  void start(DaemonConfig c = config()) {
    c.data_dir = (dir_ / "data").string();
    daemon_ = std::make_unique<Daemon>(c);
    daemon_->start();
    stub_ = v1::SimulationService::NewStub(grpc::CreateChannel(
        "127.0.0.1:" + std::to_string(daemon_->port()), grpc::InsecureChannelCredentials()));
  }

  // A client context with a deadline: gRPC sets none by default.
  static std::unique_ptr<grpc::ClientContext> ctx(
      std::chrono::seconds deadline = std::chrono::seconds(20)) {
    auto c = std::make_unique<grpc::ClientContext>();
    c->set_deadline(std::chrono::system_clock::now() + deadline);
    return c;
  }

  // The job once it is terminal, or as it is after `timeout`.
  v1::Job wait_terminal(const std::string& id,
                        std::chrono::seconds timeout = std::chrono::seconds(60)) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    v1::Job job;
    for (;;) {
      v1::GetJobRequest get;
      get.set_id(id);
      EXPECT_TRUE(stub_->GetJob(ctx().get(), get, &job).ok());
      if (job.state() >= v1::SUCCEEDED || std::chrono::steady_clock::now() > deadline) return job;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  }

  std::filesystem::path dir_;
  std::unique_ptr<Daemon> daemon_;
  std::unique_ptr<v1::SimulationService::Stub> stub_;
};

}  // namespace softshock::server::testing
