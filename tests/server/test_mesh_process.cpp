// Gmsh meshing in a softshock-mesh child (server/jobs/mesh_process.hpp): the mesh comes back
// identical to in-process meshing and lands in the cache; a stop kills the child at once; the
// child's exit status and last stderr line become the failure's reason; no handover file stays.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <filesystem>

#include "../solver/scratch_dir.hpp"
#include "server/jobs/mesh_process.hpp"
#include "solver/mesh_cache.hpp"
#include "solver/run_spec.hpp"

namespace softshock::server {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

class MeshProcess : public ::testing::Test {
 protected:
  MeshProcess() : scratch_("mesh-process") {
    command_.executable = find_mesher();
    command_.cache_dir = scratch_.str("cache");
    command_.cache_bytes = 64 << 20;
    command_.limits.mesh_root = scratch_.str("meshes");
    fs::create_directories(command_.limits.mesh_root);
    fs::create_directories(work_dir());
  }
  std::string work_dir() const { return scratch_.str("job"); }
  static v1::RunSpec gmsh_disk(int target) {
    v1::RunSpec spec;
    spec.mutable_geometry()->mutable_disk()->set_radius(90e-6);
    spec.mutable_geometry()->set_target_elements(target);
    spec.mutable_geometry()->set_mesher(v1::FRONTAL_DELAUNAY);
    return normalize_spec(spec);
  }
  void expect_no_handover_files() const {
    EXPECT_TRUE(fs::is_empty(work_dir())) << "files left in " << work_dir();
  }

  testing::ScratchDir scratch_;
  MesherCommand command_;
};

TEST_F(MeshProcess, TheChildsMeshIsTheInProcessMeshAndIsCached) {
  ASSERT_FALSE(command_.executable.empty()) << "softshock-mesh not built";
  const v1::RunSpec spec = gmsh_disk(400);
  MeshingReport report;
  const auto mesh = mesh_in_child(
      command_, spec, work_dir(), [] { return false; }, &report);
  ASSERT_TRUE(mesh.has_value());
  EXPECT_EQ(report.cache, MeshCacheOutcome::kMiss);
  EXPECT_GT(report.seconds, 0);
  const Mesh here = smooth_mesh(spec.geometry());
  EXPECT_EQ(mesh->triangles, here.triangles);
  EXPECT_EQ(mesh->x, here.x);
  EXPECT_EQ(mesh->boundary_nodes, here.boundary_nodes);
  // The child stored it where the runner looks first.
  const MeshCache cache(command_.cache_dir, command_.cache_bytes);
  const std::string material = *mesh_key_material(spec.geometry());
  ASSERT_TRUE(cache.load(mesh_cache_key(material), material).has_value());
  expect_no_handover_files();
}

TEST_F(MeshProcess, AStopKillsTheChildAtOnce) {
  ASSERT_FALSE(command_.executable.empty()) << "softshock-mesh not built";
  // ~1.5M triangles: over a minute of Gmsh here, unless killed.
  const v1::RunSpec spec = gmsh_disk(1'500'000);
  const auto started = Clock::now();
  const auto stop_after = started + std::chrono::milliseconds(300);
  const auto mesh =
      mesh_in_child(command_, spec, work_dir(), [&] { return Clock::now() > stop_after; });
  const double seconds = std::chrono::duration<double>(Clock::now() - started).count();
  EXPECT_FALSE(mesh.has_value());
  EXPECT_LT(seconds, 1.0) << "the child was not killed";
  expect_no_handover_files();
}

TEST_F(MeshProcess, AnInvalidSpecIsTheChildsJudgementWithoutServerPaths) {
  ASSERT_FALSE(command_.executable.empty()) << "softshock-mesh not built";
  v1::RunSpec spec;
  spec.mutable_geometry()->set_mesh_file("absent.msh");
  spec = with_defaults(spec);
  try {
    (void)mesh_in_child(command_, spec, work_dir(), [] { return false; });
    FAIL() << "no MeshingFailed";
  } catch (const MeshingFailed& e) {
    EXPECT_TRUE(e.invalid_spec());
    EXPECT_EQ(std::string(e.what()).rfind("geometry.mesh_file: ", 0), 0u) << e.what();
    EXPECT_EQ(std::string(e.what()).find(scratch_.str()), std::string::npos) << e.what();
  }
  // The element limit is the daemon's, passed on (the child validates against it).
  command_.limits.max_elements = 100;
  try {
    (void)mesh_in_child(command_, gmsh_disk(400), work_dir(), [] { return false; });
    FAIL() << "no MeshingFailed";
  } catch (const MeshingFailed& e) {
    EXPECT_TRUE(e.invalid_spec());
    EXPECT_EQ(std::string(e.what()), "geometry.target_elements: must be between 20 and 100");
  }
  expect_no_handover_files();
}

TEST_F(MeshProcess, AMesherThatCannotRunOrDiesIsAFailureWithItsReason) {
  command_.executable = scratch_.str("no-such-mesher");
  try {
    (void)mesh_in_child(command_, gmsh_disk(400), work_dir(), [] { return false; });
    FAIL() << "no MeshingFailed";
  } catch (const MeshingFailed& e) {
    EXPECT_FALSE(e.invalid_spec());
    EXPECT_NE(std::string(e.what()).find("cannot run"), std::string::npos) << e.what();
  }
  // A mesher killed by a signal (here: one that kills itself) is named with the signal.
  const std::string script = scratch_.str("suicide.sh");
  {
    FILE* f = std::fopen(script.c_str(), "w");
    ASSERT_NE(f, nullptr);
    std::fputs("#!/bin/sh\necho 'gmsh: out of memory' >&2\nkill -SEGV $$\n", f);
    std::fclose(f);
    fs::permissions(script, fs::perms::owner_all);
  }
  command_.executable = script;
  try {
    (void)mesh_in_child(command_, gmsh_disk(400), work_dir(), [] { return false; });
    FAIL() << "no MeshingFailed";
  } catch (const MeshingFailed& e) {
    EXPECT_FALSE(e.invalid_spec());
    const std::string what = e.what();
    EXPECT_NE(what.find("signal 11"), std::string::npos) << what;
    EXPECT_NE(what.find("gmsh: out of memory"), std::string::npos) << what;
  }
  expect_no_handover_files();
}

}  // namespace
}  // namespace softshock::server
