// Values a careless or hostile client (or a diverged run) can feed the daemon, each of which
// used to reach undefined behaviour or a weak default: non-finite and tangled raster inputs,
// non-finite counts in a summary JSON, out-of-range timestamps, weak or exposed token files,
// and a token served in clear text off loopback.
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <random>

#include "server/daemon.hpp"
#include "server/daemon_config.hpp"
#include "server/jobs/job_runner.hpp"
#include "server/transport/auth.hpp"
#include "server/transport/field_raster.hpp"
#include "softshock/v1/service.grpc.pb.h"

namespace softshock::server {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

class HostileValues : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ =
        fs::temp_directory_path() / ("softshock-hostile-" + std::to_string(std::random_device{}()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string token_file(const std::string& content, fs::perms perms) {
    const fs::path p = dir_ / "token";
    std::ofstream(p, std::ios::trunc) << content;
    fs::permissions(p, perms);
    return p.string();
  }

  fs::path dir_;
};

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

TEST_F(HostileValues, RasterLeavesOutNonFiniteNodesAndTheirTriangles) {
  // The unit square in two triangles, and a third triangle through a node that diverged.
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> x{0, 1, 1, 0, nan, std::numeric_limits<double>::infinity()};
  std::vector<double> y{0, 0, 1, 1, 0.5, 0.5};
  std::vector<std::array<int32_t, 3>> tris{{0, 1, 2}, {0, 2, 3}, {1, 4, 2}, {1, 5, 2}};
  RasterBox box;
  const auto r = rasterize(x, y, tris, {10, 20, 30, 40}, 1, false, 4, 4, box);
  EXPECT_EQ(box.x_min, 0);
  EXPECT_EQ(box.x_max, 1) << "the box spans the finite nodes only";
  EXPECT_EQ(box.y_max, 1);
  EXPECT_EQ(r[0 * 4 + 3], 10);  // (0.875, 0.125): below the diagonal
  EXPECT_EQ(r[3 * 4 + 0], 20);  // (0.125, 0.875): above it
  for (double v : r) EXPECT_TRUE(v == 10 || v == 20) << v;

  std::vector<double> all_nan(3, nan);
  const auto none = rasterize(all_nan, all_nan, {{0, 1, 2}}, {1}, 1, false, 2, 2, box);
  for (double v : none) EXPECT_TRUE(std::isnan(v));
}

TEST_F(HostileValues, RasterRefusesATangledMeshInsteadOfOverflowingItsCounters) {
  // 50,000 copies of one triangle over the whole box: 50,000 x 223^2 = 2.5e9 bucket entries,
  // more than an int32 counter holds.
  std::vector<double> x{0, 1, 0}, y{0, 0, 1};
  std::vector<std::array<int32_t, 3>> tris(50'000, {0, 1, 2});
  std::vector<double> values(tris.size(), 1.0);
  RasterBox box;
  const std::string e = error_of([&] { rasterize(x, y, tris, values, 1, false, 8, 8, box); });
  EXPECT_NE(e.find("too tangled"), std::string::npos) << e;
}

TEST_F(HostileValues, SummaryCountsThatAreNotFiniteOrTooLargeReadAsZero) {
  const RunSummary r = parse_summary_json(
      R"({"elements": null, "nodes": 1e300, "steps": -5, "dominant_mode_end": 1e12,
          "max_abar": 0.5})");
  EXPECT_EQ(r.elements, 0u);
  EXPECT_EQ(r.nodes, 0u);
  EXPECT_EQ(r.steps, 0);
  EXPECT_EQ(r.dominant_mode_end, 0);
  EXPECT_EQ(r.max_abar, 0.5);
  EXPECT_EQ(parse_summary_json(R"({"elements": 412, "steps": 987})").elements, 412u);
}

TEST_F(HostileValues, TokenFilesMustBeLongAndPrivate) {
  const std::string good(40, 'k');
  const auto owner = fs::perms::owner_read | fs::perms::owner_write;
  EXPECT_EQ(read_token_file(token_file(good + "\n", owner)), good);
  EXPECT_EQ(read_token_file(token_file(good, owner | fs::perms::group_read)), good)
      << "0640: the daemon's group may read it (Kubernetes fsGroup)";
  const std::string short_token =
      error_of([&] { read_token_file(token_file("  short\n", owner)); });
  EXPECT_NE(short_token.find("at least 32"), std::string::npos) << short_token;
  for (auto others : {fs::perms::others_read, fs::perms::others_write}) {
    const std::string exposed =
        error_of([&] { read_token_file(token_file(good, owner | others)); });
    EXPECT_NE(exposed.find("accessible to other users"), std::string::npos) << exposed;
  }
  fs::create_directories(dir_ / "folder");
  EXPECT_FALSE(error_of([&] { read_token_file((dir_ / "folder").string()); }).empty());
}

TEST_F(HostileValues, ATokenInClearTextOffLoopbackIsWarnedAbout) {
  DaemonConfig c;
  c.listen = "0.0.0.0:50051";
  c.token_file = "/run/secrets/token";
  const auto warning = transport_warning(c);
  ASSERT_TRUE(warning.has_value());
  EXPECT_NE(warning->find("without TLS"), std::string::npos) << *warning;
  c.tls_cert = "cert.pem";
  c.tls_key = "key.pem";
  EXPECT_FALSE(transport_warning(c).has_value()) << "TLS on";
  c = DaemonConfig{};
  c.token_file = "/run/secrets/token";
  EXPECT_FALSE(transport_warning(c).has_value()) << "loopback";
}

TEST_F(HostileValues, OutOfRangeTimestampsAreInvalidArguments) {
  DaemonConfig c;
  c.data_dir = (dir_ / "data").string();
  c.listen = "127.0.0.1:0";
  c.workers = 1;
  Daemon daemon(c);
  daemon.start();
  auto stub = v1::SimulationService::NewStub(grpc::CreateChannel(
      "127.0.0.1:" + std::to_string(daemon.port()), grpc::InsecureChannelCredentials()));
  auto list = [&](int64_t seconds, int32_t nanos, bool after) {
    v1::ListJobsRequest req;
    auto* t = after ? req.mutable_created_after() : req.mutable_created_before();
    t->set_seconds(seconds);
    t->set_nanos(nanos);
    grpc::ClientContext ctx;
    ctx.set_deadline(std::chrono::system_clock::now() + 10s);
    v1::ListJobsResponse resp;
    return stub->ListJobs(&ctx, req, &resp);
  };
  for (auto [seconds, nanos] : {std::pair<int64_t, int32_t>{std::numeric_limits<int64_t>::max(), 0},
                                {std::numeric_limits<int64_t>::min(), 0},
                                {0, -1},
                                {0, 1'000'000'000}}) {
    for (bool after : {true, false}) {
      const grpc::Status s = list(seconds, nanos, after);
      EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << seconds << " " << nanos;
      EXPECT_EQ(s.error_message().rfind(after ? "created_after: " : "created_before: ", 0), 0u)
          << s.error_message();
    }
  }
  EXPECT_TRUE(list(1'700'000'000, 0, true).ok());
  daemon.stop();
}

}  // namespace
}  // namespace softshock::server
