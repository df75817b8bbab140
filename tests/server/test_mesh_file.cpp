// geometry.mesh_file through softshockd: resolved inside DATA/meshes/ only (symlinks included),
// one answer for "absent" and "not allowed", and a real .msh submitted through the daemon runs.
#include <grpcpp/grpcpp.h>
#include <gtest/gtest.h>

#include <array>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <thread>

#include "daemon_fixture.hpp"
#include "server/daemon.hpp"
#include "softshock/v1/service.grpc.pb.h"
#include "solver/mesh_file_path.hpp"
#include "solver/run_spec.hpp"

namespace softshock::server {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

// A disk of radius r in MSH 4.1 ASCII: the centre, 6 nodes at r/2 and 12 on the rim; 24
// triangles (6 inner, 18 in the outer ring), one surface entity.
std::string disk_msh(double r) {
  std::vector<std::pair<double, double>> nodes = {{0, 0}};
  for (int k = 0; k < 6; ++k) {
    nodes.emplace_back(0.5 * r * std::cos(k * M_PI / 3), 0.5 * r * std::sin(k * M_PI / 3));
  }
  for (int k = 0; k < 12; ++k) {
    nodes.emplace_back(r * std::cos(k * M_PI / 6), r * std::sin(k * M_PI / 6));
  }
  std::vector<std::array<int, 3>> tris;
  auto inner = [](int k) { return 2 + (k % 6); };  // node tags are 1-based
  auto outer = [](int k) { return 8 + (k % 12); };
  for (int k = 0; k < 6; ++k) tris.push_back({1, inner(k), inner(k + 1)});
  for (int k = 0; k < 6; ++k) {
    // Inner node k sits at the angle of rim node 2k.
    tris.push_back({inner(k), outer(2 * k), outer(2 * k + 1)});
    tris.push_back({inner(k), outer(2 * k + 1), inner(k + 1)});
    tris.push_back({inner(k + 1), outer(2 * k + 1), outer(2 * k + 2)});
  }
  std::ostringstream m;
  m.precision(17);
  m << "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Entities\n0 0 1 0\n1 " << -r << " " << -r << " 0 "
    << r << " " << r << " 0 0 0\n$EndEntities\n$Nodes\n1 " << nodes.size() << " 1 " << nodes.size()
    << "\n2 1 0 " << nodes.size() << "\n";
  for (std::size_t i = 1; i <= nodes.size(); ++i) m << i << "\n";
  for (const auto& [x, y] : nodes) m << x << " " << y << " 0\n";
  m << "$EndNodes\n$Elements\n1 " << tris.size() << " 1 " << tris.size() << "\n2 1 2 "
    << tris.size() << "\n";
  for (std::size_t i = 0; i < tris.size(); ++i) {
    m << i + 1 << " " << tris[i][0] << " " << tris[i][1] << " " << tris[i][2] << "\n";
  }
  m << "$EndElements\n";
  return m.str();
}

class MeshFileTest : public testing::DaemonFixture {
 protected:
  MeshFileTest() : DaemonFixture("mesh") {}
  void SetUp() override {
    meshes_ = dir_ / "data" / "meshes";
    fs::create_directories(meshes_ / "studies");
    std::ofstream(meshes_ / "disk.msh") << disk_msh(50e-6);
    std::ofstream(meshes_ / "studies" / "disk.msh") << disk_msh(50e-6);
    std::ofstream(dir_ / "outside.msh") << disk_msh(50e-6);  // exists, but not in meshes/
    fs::create_symlink(dir_ / "outside.msh", meshes_ / "escape.msh");
    fs::create_symlink(meshes_ / "disk.msh", meshes_ / "alias.msh");
  }

  grpc::Status submit(const std::string& mesh_file, v1::Job* job) {
    v1::SubmitJobRequest req;
    req.mutable_spec()->mutable_geometry()->set_mesh_file(mesh_file);
    req.mutable_spec()->mutable_run()->set_end_time(5e-9);
    req.mutable_spec()->mutable_run()->set_output_interval(2.5e-9);
    grpc::ClientContext ctx;
    ctx.set_deadline(std::chrono::system_clock::now() + 10s);
    return stub_->SubmitJob(&ctx, req, job);
  }

  fs::path meshes_;
};

std::string resolve_error(const std::string& root, const std::string& name) {
  try {
    resolve_mesh_file(root, name);
  } catch (const SpecError& e) {
    EXPECT_EQ(e.field(), "geometry.mesh_file");
    return e.what();
  }
  return "";
}

TEST_F(MeshFileTest, ResolvesInsideTheFolderOnlyWithOneAnswerForEveryRefusal) {
  const std::string root = meshes_.string();
  const std::string canonical_root = fs::canonical(meshes_).string();
  EXPECT_EQ(resolve_mesh_file(root, "disk.msh"), canonical_root + "/disk.msh");
  EXPECT_EQ(resolve_mesh_file(root, "studies/disk.msh"), canonical_root + "/studies/disk.msh");
  EXPECT_EQ(resolve_mesh_file(root, "alias.msh"), canonical_root + "/disk.msh")
      << "a symlink that stays inside is fine";
  const std::string absent = resolve_error(root, "no_such.msh");
  ASSERT_FALSE(absent.empty());
  for (const std::string& name :
       {std::string("escape.msh"), (dir_ / "outside.msh").string(), std::string("/etc/passwd"),
        std::string("../outside.msh"), std::string("studies/../../outside.msh"),
        std::string("studies"), std::string(""), std::string("disk.msh\0/x", 10),
        std::string(2000, 'a')}) {
    EXPECT_EQ(resolve_error(root, name), absent) << "'" << name << "'";
  }
  EXPECT_EQ(absent.find(dir_.string()), std::string::npos) << "no server path in: " << absent;
}

TEST_F(MeshFileTest, ARealMeshFileRunsThroughTheDaemon) {
  start();
  v1::Job job;
  grpc::Status s = submit("disk.msh", &job);
  ASSERT_TRUE(s.ok()) << s.error_message();
  job = wait_terminal(job.id());
  ASSERT_EQ(job.state(), v1::SUCCEEDED) << job.reason() << ": " << job.error();
  EXPECT_EQ(job.spec().geometry().mesh_file(), "disk.msh") << "stored as the client named it";
  grpc::ClientContext ctx;
  v1::GetJobSummaryRequest sreq;
  sreq.set_id(job.id());
  v1::JobSummary summary;
  ASSERT_TRUE(stub_->GetJobSummary(&ctx, sreq, &summary).ok());
  EXPECT_EQ(summary.elements(), 24);
  EXPECT_EQ(summary.nodes(), 19);
}

TEST_F(MeshFileTest, TheDaemonAnswersAbsentAndNotAllowedAlike) {
  start();
  v1::Job job;
  const grpc::Status absent = submit("no_such.msh", &job);
  ASSERT_EQ(absent.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(absent.error_message().rfind("spec.geometry.mesh_file: ", 0), 0u)
      << absent.error_message();
  for (const std::string& name :
       {std::string("/etc/passwd"), std::string("escape.msh"), std::string("../catalogue.sqlite"),
        (dir_ / "outside.msh").string()}) {
    const grpc::Status s = submit(name, &job);
    EXPECT_EQ(s.error_code(), grpc::StatusCode::INVALID_ARGUMENT) << name;
    EXPECT_EQ(s.error_message(), absent.error_message()) << name;
  }
}

}  // namespace
}  // namespace softshock::server
