// The writer thread (solver/io/async_result_writer.hpp): tasks in submission order, bounded
// queue with back-pressure, errors reported to the submitter and later tasks skipped, queued
// work dropped on destruction; AsyncResultWriter's files equal to the ResultWriter contract
// (frames in order, complete only after finish), and a process killed mid-write leaving no
// result.h5.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <filesystem>
#include <future>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "scratch_dir.hpp"
#include "solver/io/async_result_writer.hpp"
#include "tet_box.hpp"

namespace softshock {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

// ScratchDir(prefix): tests/solver/scratch_dir.hpp.
class ScratchDir : public testing::ScratchDir {
 public:
  ScratchDir() : testing::ScratchDir("async") {}
};

Mesh small_mesh() {
  return make_rectangle_mesh(1.0, 1.0, 8, 8);
}

FieldFrame make_frame(const Mesh& mesh, double time_s) {
  FieldFrame f;
  f.time_s = time_s;
  f.dimension = mesh.dimension();
  const std::size_t n = mesh.node_count(), e = mesh.element_count();
  for (std::size_t i = 0; i < static_cast<std::size_t>(f.dimension) * n; ++i) {
    f.displacement.push_back(time_s * 1e9 + static_cast<double>(i));
    f.velocity.push_back(-static_cast<double>(i) / 3.0);
  }
  for (std::size_t i = 0; i < e; ++i) {
    f.J.push_back(1.0 + static_cast<double>(i) * 1e-6);
    f.mean_stress.push_back(time_s);
    f.radial_stress.push_back(1.0);
    f.hoop_stress.push_back(2.0);
    f.von_mises.push_back(3.0);
    f.aspect_ratio.push_back(1.2);
  }
  return f;
}

History make_history(std::size_t samples) {
  History h;
  for (const auto& [name, column] : h.columns()) {
    auto* v = const_cast<std::vector<double>*>(column);
    for (std::size_t k = 0; k < samples; ++k) v->push_back(1e-9 * static_cast<double>(k));
  }
  for (std::size_t k = 0; k < samples; ++k) h.modes.push_back({1.0, 0.5, 0.25});
  return h;
}

RunSummary make_summary(const Mesh& mesh) {
  RunSummary s;
  s.nodes = mesh.node_count();
  s.elements = mesh.element_count();
  s.steps = 10;
  s.status = "completed";
  return s;
}

TEST(OrderedWorker, RunsTasksInSubmissionOrder) {
  std::vector<int> seen;
  {
    OrderedWorker worker(3);
    for (int i = 0; i < 200; ++i) worker.submit([&seen, i] { seen.push_back(i); });
    worker.drain();
  }
  ASSERT_EQ(seen.size(), 200u);
  for (int i = 0; i < 200; ++i) EXPECT_EQ(seen[static_cast<std::size_t>(i)], i);
}

TEST(OrderedWorker, FullQueueBlocksTheSubmitter) {
  OrderedWorker worker(2);
  std::promise<void> release;
  std::shared_future<void> gate = release.get_future().share();
  std::atomic<int> ran{0};
  worker.submit([gate, &ran] {
    gate.wait();
    ++ran;
  });
  // Once the first task runs, two more fill the queue and a third must wait.
  std::this_thread::sleep_for(20ms);
  worker.submit([&ran] { ++ran; });
  worker.submit([&ran] { ++ran; });
  std::atomic<bool> returned{false};
  std::thread submitter([&] {
    worker.submit([&ran] { ++ran; });
    returned = true;
  });
  std::this_thread::sleep_for(100ms);
  EXPECT_FALSE(returned.load()) << "a third waiting task was accepted beyond the capacity of 2";
  release.set_value();
  submitter.join();
  EXPECT_TRUE(returned.load());
  worker.drain();
  EXPECT_EQ(ran.load(), 4);
}

TEST(OrderedWorker, AFailureReachesTheSubmitterAndSkipsLaterTasks) {
  OrderedWorker worker(8);
  std::promise<void> release;
  std::shared_future<void> gate = release.get_future().share();
  std::atomic<int> after{0};
  worker.submit([gate] {
    gate.wait();
    throw std::runtime_error("disk full");
  });
  worker.submit([&after] { ++after; });  // queued behind the failing task
  release.set_value();
  try {
    worker.drain();
    ADD_FAILURE() << "drain() did not report the failure";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "disk full");
  }
  EXPECT_EQ(after.load(), 0);
  EXPECT_THROW(worker.submit([&after] { ++after; }), std::runtime_error);
  EXPECT_EQ(after.load(), 0);
}

TEST(OrderedWorker, DestructionDropsWaitingTasks) {
  std::atomic<int> ran{0};
  std::promise<void> release;
  std::shared_future<void> gate = release.get_future().share();
  std::promise<void> started;
  std::thread releaser;
  {
    OrderedWorker worker(8);
    worker.submit([gate, &started, &ran] {
      started.set_value();
      gate.wait();
      ++ran;
    });
    for (int i = 0; i < 5; ++i) worker.submit([&ran] { ran += 100; });
    started.get_future().wait();
    releaser = std::thread([&] {
      std::this_thread::sleep_for(20ms);  // the destructor below is waiting by then
      release.set_value();
    });
  }  // the running task ends; the five waiting ones never run
  releaser.join();
  EXPECT_EQ(ran.load(), 1);
}

TEST(AsyncResultWriter, WritesFramesInOrderAndCompletesOnlyOnFinish) {
  ScratchDir dir;
  const Mesh mesh = small_mesh();
  {
    AsyncResultWriter writer(dir.str("out"), mesh, "{}", "test", 2);
    for (int k = 0; k < 12; ++k) writer.write_frame(make_frame(mesh, 1e-9 * k));
    EXPECT_FALSE(fs::exists(dir.str("out/result.h5")));
    writer.finish(make_history(5), make_summary(mesh), true, "");
    EXPECT_TRUE(fs::exists(writer.h5_path()));
  }
  ResultReader reader(dir.str("out/result.h5"));
  EXPECT_TRUE(reader.info().complete);
  // The mesh, written by the writer thread from its own copy.
  const Mesh back = reader.mesh();
  EXPECT_EQ(back.x, mesh.x);
  EXPECT_EQ(back.y, mesh.y);
  EXPECT_EQ(back.triangles, mesh.triangles);
  EXPECT_EQ(back.boundary_nodes, mesh.boundary_nodes);
  ASSERT_EQ(reader.info().frame_times.size(), 12u);
  for (std::size_t k = 0; k < 12; ++k) {
    EXPECT_EQ(reader.info().frame_times[k], 1e-9 * static_cast<double>(k));
    EXPECT_EQ(reader.field(k, "displacement"),
              make_frame(mesh, 1e-9 * static_cast<double>(k)).displacement);
  }
  EXPECT_EQ(reader.series("time").size(), 5u);
  EXPECT_FALSE(fs::exists(dir.str("out/result.h5.tmp")));
}

// A 3-D run through the writer thread: the tetrahedral mesh (written from the thread's copy) and
// N x 3 node vectors come back as they went in.
TEST(AsyncResultWriter, WritesA3dResult) {
  ScratchDir dir;
  const Mesh mesh = testing::tet_box(1.0, 0.5, 0.25, 4, 2, 2);
  {
    AsyncResultWriter writer(dir.str("out"), mesh, "{}", "test", 2);
    for (int k = 0; k < 5; ++k) writer.write_frame(make_frame(mesh, 1e-9 * k));
    writer.finish(make_history(3), make_summary(mesh), true, "");
  }
  ResultReader reader(dir.str("out/result.h5"));
  EXPECT_EQ(reader.info().dimension, 3);
  const Mesh back = reader.mesh();
  EXPECT_EQ(back.z, mesh.z);
  EXPECT_EQ(back.tetrahedra, mesh.tetrahedra);
  EXPECT_EQ(back.boundary_faces, mesh.boundary_faces);
  ASSERT_EQ(reader.info().frame_times.size(), 5u);
  for (std::size_t k = 0; k < 5; ++k) {
    const FieldFrame want = make_frame(mesh, 1e-9 * static_cast<double>(k));
    EXPECT_EQ(reader.field(k, "displacement"), want.displacement);
    EXPECT_EQ(reader.field(k, "velocity"), want.velocity);
    EXPECT_EQ(reader.field(k, "von_mises"), want.von_mises);
  }
}

// Spares (RunControl::spare_frame): only frames already written come back, at most two, and
// frames filled into them are written as they were handed over.
TEST(AsyncResultWriter, SpareFramesAreWrittenFramesAndFillCorrectly) {
  ScratchDir dir;
  const Mesh mesh = small_mesh();
  AsyncResultWriter writer(dir.str("out"), mesh, "{}", "test", 2);
  EXPECT_TRUE(writer.spare_frame().J.empty());  // nothing written yet
  std::size_t reused = 0;
  for (int k = 0; k < 12; ++k) {
    FieldFrame f = writer.spare_frame();
    reused += f.J.empty() ? 0 : 1;
    const FieldFrame want = make_frame(mesh, 1e-9 * k);
    f.time_s = want.time_s;
    f.displacement = want.displacement, f.velocity = want.velocity, f.J = want.J;
    f.mean_stress = want.mean_stress, f.radial_stress = want.radial_stress;
    f.hoop_stress = want.hoop_stress, f.von_mises = want.von_mises;
    f.aspect_ratio = want.aspect_ratio;
    writer.write_frame(std::move(f));
    std::this_thread::sleep_for(2ms);  // the writer catches up: its frames become spares
  }
  EXPECT_GT(reused, 0u);
  writer.finish(make_history(2), make_summary(mesh), true, "");
  int spares = 0;
  while (!writer.spare_frame().J.empty()) ++spares;
  EXPECT_LE(spares, 2);
  ResultReader reader(dir.str("out/result.h5"));
  ASSERT_EQ(reader.info().frame_times.size(), 12u);
  for (std::size_t k = 0; k < 12; ++k) {
    const FieldFrame want = make_frame(mesh, 1e-9 * static_cast<double>(k));
    EXPECT_EQ(reader.info().frame_times[k], want.time_s);
    EXPECT_EQ(reader.field(k, "displacement"), want.displacement);
    EXPECT_EQ(reader.field(k, "J"), want.J);
  }
}

TEST(AsyncResultWriter, WithoutFinishNothingStaysBehind) {
  ScratchDir dir;
  const Mesh mesh = small_mesh();
  {
    AsyncResultWriter writer(dir.str("out"), mesh, "{}", "test");
    for (int k = 0; k < 6; ++k) writer.write_frame(make_frame(mesh, 1e-9 * k));
  }
  EXPECT_FALSE(fs::exists(dir.str("out/result.h5")));
  EXPECT_FALSE(fs::exists(dir.str("out/result.h5.tmp")));
}

TEST(AsyncResultWriter, AWriteErrorReachesTheSolverAndNoResultIsNamedComplete) {
  ScratchDir dir;
  const Mesh mesh = small_mesh();
  AsyncResultWriter writer(dir.str("out"), mesh, "{}", "test");
  writer.write_frame(make_frame(mesh, 0.0));
  FieldFrame bad = make_frame(mesh, 1e-9);
  bad.J.pop_back();  // the writer thread rejects it
  writer.write_frame(bad);
  // Reported at the next hand-over at the latest (finish() drains first).
  bool reported = false;
  try {
    for (int k = 2; k < 50; ++k) {
      writer.write_frame(make_frame(mesh, 1e-9 * k));
      std::this_thread::sleep_for(2ms);
    }
  } catch (const std::invalid_argument& e) {
    reported = std::string(e.what()).find("field J") != std::string::npos;
  }
  EXPECT_TRUE(reported);
  EXPECT_THROW(writer.finish(make_history(3), make_summary(mesh), true, ""), std::invalid_argument);
  EXPECT_FALSE(fs::exists(dir.str("out/result.h5")));
}

TEST(AsyncResultWriter, KilledMidWriteLeavesNoResultFile) {
  ScratchDir dir;
  const Mesh mesh = make_rectangle_mesh(1.0, 1.0, 80, 80);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    AsyncResultWriter writer(dir.str("out"), mesh, "{}", "test");
    for (int k = 0;; ++k) writer.write_frame(make_frame(mesh, 1e-9 * k));
  }
  const auto deadline = std::chrono::steady_clock::now() + 30s;
  while (!fs::exists(dir.str("out/result.h5.tmp")) && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(5ms);
  std::this_thread::sleep_for(50ms);  // frames in flight
  ::kill(child, SIGKILL);
  int status = 0;
  ::waitpid(child, &status, 0);
  EXPECT_TRUE(WIFSIGNALED(status));
  EXPECT_TRUE(fs::exists(dir.str("out/result.h5.tmp")));
  EXPECT_FALSE(fs::exists(dir.str("out/result.h5")));
}

}  // namespace
}  // namespace softshock
