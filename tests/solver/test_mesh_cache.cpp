// The mesh cache (solver/mesh_cache.hpp): exact round trip (2-D and 3-D), cached = fresh, keys,
// corruption and inconsistent arrays detected and rebuilt, LRU eviction by bytes, concurrent
// builders and readers, kill -9 while storing, and a hit that never loads Gmsh.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <thread>
#include <vector>

#include "scratch_dir.hpp"
#include "solver/gmsh_mesher.hpp"
#include "solver/mesh_cache.hpp"
#include "solver/run_spec.hpp"

namespace softshock {
namespace {

namespace fs = std::filesystem;

// ScratchDir(prefix): tests/solver/scratch_dir.hpp.
class ScratchDir : public testing::ScratchDir {
 public:
  ScratchDir() : testing::ScratchDir("mesh-cache") {}
};

// Byte-for-byte equality of every array (== on doubles would let -0.0 and 0.0 pass).
template <typename T>
bool same_bytes(const std::vector<T>& a, const std::vector<T>& b) {
  // Empty vectors may have a null data(), which memcmp must not see even for zero bytes.
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}
void expect_identical(const Mesh& a, const Mesh& b) {
  EXPECT_TRUE(same_bytes(a.x, b.x));
  EXPECT_TRUE(same_bytes(a.y, b.y));
  EXPECT_TRUE(same_bytes(a.triangles, b.triangles));
  EXPECT_TRUE(same_bytes(a.boundary_edges, b.boundary_edges));
  EXPECT_TRUE(same_bytes(a.boundary_nodes, b.boundary_nodes));
  EXPECT_TRUE(same_bytes(a.z, b.z));
  EXPECT_TRUE(same_bytes(a.tetrahedra, b.tetrahedra));
  EXPECT_TRUE(same_bytes(a.boundary_faces, b.boundary_faces));
}

v1::Geometry disk(double radius, int target) {
  v1::Geometry g;
  g.mutable_disk()->set_radius(radius);
  g.set_target_elements(target);
  return g;
}

std::string material_of(const v1::Geometry& g) {
  const auto m = mesh_key_material(g);
  EXPECT_TRUE(m.has_value());
  return m.value_or("");
}

TEST(MeshCache, RoundTripIsExact) {
  ScratchDir dir;
  const MeshCache cache(dir.str(), 1 << 20);
  Mesh mesh = make_rectangle_mesh(1.0 / 3.0, 0.7, 7, 5);
  mesh.x[0] = -0.0;  // a sign a lossy path would drop
  cache.store("k1", "material", mesh);
  bool unusable = true;
  const auto back = cache.load("k1", "material", &unusable);
  ASSERT_TRUE(back.has_value());
  EXPECT_FALSE(unusable);
  expect_identical(mesh, *back);
  EXPECT_FALSE(cache.load("absent", "material", &unusable).has_value());
  EXPECT_FALSE(unusable);
}

TEST(MeshCache, RoundTripOfATetMeshIsExact) {
  ScratchDir dir;
  const MeshCache cache(dir.str(), 1 << 20);
  Mesh mesh = make_corrugated_box_mesh(1.0 / 3.0, 0.7, 0.3, 0.01, 3.0, 5.0, 500);
  mesh.z[0] = -0.0;  // a sign a lossy path would drop
  ASSERT_EQ(mesh.dimension(), 3);
  cache.store("k3", "material", mesh);
  bool unusable = true;
  const auto back = cache.load("k3", "material", &unusable);
  ASSERT_TRUE(back.has_value());
  EXPECT_FALSE(unusable);
  EXPECT_EQ(back->dimension(), 3);
  expect_identical(mesh, *back);
  // A 2-D entry beside it still reads back as 2-D, with no 3-D arrays.
  const Mesh flat = make_rectangle_mesh(1.0, 2.0, 3, 4);
  cache.store("k2", "material", flat);
  const auto flat_back = cache.load("k2", "material");
  ASSERT_TRUE(flat_back.has_value());
  EXPECT_EQ(flat_back->dimension(), 2);
  expect_identical(flat, *flat_back);
  // The one-file form softshock-mesh hands over.
  const std::string path = dir.str("entry.mesh");
  write_mesh_entry(path, "material", mesh);
  const auto entry = read_mesh_entry(path, "material");
  ASSERT_TRUE(entry.has_value());
  expect_identical(mesh, *entry);
}

TEST(MeshCache, InconsistentTetEntriesAreUnusable) {
  ScratchDir dir;
  const MeshCache cache(dir.str(), 1 << 20);
  const Mesh box = make_box_mesh(1.0, 1.0, 1.0, 2, 2, 2);
  auto unusable_after = [&](const std::function<void(Mesh&)>& spoil) {
    Mesh m = box;
    spoil(m);
    cache.store("bad", "material", m);  // stored as given: store() does not check
    bool unusable = false;
    const bool loaded = cache.load("bad", "material", &unusable).has_value();
    return !loaded && unusable;
  };
  EXPECT_FALSE(unusable_after([](Mesh&) {}));
  EXPECT_TRUE(unusable_after([](Mesh& m) { m.z.pop_back(); }));
  EXPECT_TRUE(unusable_after([](Mesh& m) { m.tetrahedra[3][2] = 27; }));  // 27 nodes: 0..26
  EXPECT_TRUE(unusable_after([](Mesh& m) { m.boundary_faces[5][0] = -1; }));
  EXPECT_TRUE(unusable_after([](Mesh& m) { m.triangles = {{0, 1, 2}}; }));  // 2-D and 3-D
  EXPECT_TRUE(unusable_after([](Mesh& m) { m.tetrahedra.clear(); }));       // z but no elements
}

TEST(MeshCache, KeysCoverEveryGeometryField) {
  const std::string base = mesh_cache_key(material_of(disk(90e-6, 16500)));
  EXPECT_EQ(base, mesh_cache_key(material_of(disk(90e-6, 16500))));
  EXPECT_NE(base, mesh_cache_key(material_of(disk(90e-6, 16501))));
  EXPECT_NE(base, mesh_cache_key(material_of(disk(std::nextafter(90e-6, 1.0), 16500))));
  v1::Geometry square;
  square.mutable_rounded_square()->set_side(180e-6);
  square.mutable_rounded_square()->set_corner_radius(20e-6);
  square.set_target_elements(16500);
  const std::string sq = mesh_cache_key(material_of(square));
  EXPECT_NE(base, sq);
  square.mutable_rounded_square()->set_corner_radius(21e-6);
  EXPECT_NE(sq, mesh_cache_key(material_of(square)));
  // Through the spec path: JSON field order and 1 vs 1.0 do not matter.
  const auto a = normalize_spec(
      parse_spec_json(R"({"geometry": {"target_elements": 900, "disk": {"radius": 1}}})"));
  const auto b = normalize_spec(
      parse_spec_json(R"({"geometry": {"disk": {"radius": 1.0}, "target_elements": 900}})"));
  EXPECT_EQ(material_of(a.geometry()), material_of(b.geometry()));
  // A mesh file is not cached (its content may change under the same name).
  v1::Geometry file;
  file.set_mesh_file("some.msh");
  EXPECT_FALSE(mesh_key_material(file).has_value());
}

TEST(MeshCache, CachedMeshIsByteIdenticalToAFreshOne) {
  ScratchDir dir;
  const MeshCache cache(dir.str(), 64 << 20);
  const auto spec = normalize_spec(
      parse_spec_json(R"({"geometry": {"disk": {"radius": 90e-6}, "target_elements": 1500,
                       "mesher": "FRONTAL_DELAUNAY", "rim_roughness": {"amplitude": 0}}})"));
  MeshingReport first, second;
  const Problem built = make_problem(spec, {}, &cache, &first);
  const Problem cached = make_problem(spec, {}, &cache, &second);
  EXPECT_EQ(first.cache, MeshCacheOutcome::kMiss);
  EXPECT_EQ(second.cache, MeshCacheOutcome::kHit);
  const Mesh fresh = mesh_disk(90e-6, 1500);
  expect_identical(fresh, built.mesh);
  expect_identical(fresh, cached.mesh);
  EXPECT_EQ(cached.reference_radius_m, 90e-6);
}

TEST(MeshCache, CorruptEntryIsDetectedAndRebuilt) {
  ScratchDir dir;
  const MeshCache cache(dir.str(), 1 << 20);
  const Mesh mesh = make_rectangle_mesh(1.0, 1.0, 6, 6);
  int builds = 0;
  auto build = [&] {
    ++builds;
    return mesh;
  };
  MeshCacheOutcome outcome{};
  cache.get_or_build("k", "m", build, &outcome);
  EXPECT_EQ(outcome, MeshCacheOutcome::kMiss);
  const std::string path = cache.entry_path("k");
  const auto size = fs::file_size(path);
  {  // one flipped mantissa bit in a coordinate (x[1]: after the 48-byte header and "m")
    std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
    const std::streamoff at = 48 + 1 + 8 + 2;
    f.seekg(at);
    char c = 0;
    f.read(&c, 1);
    c ^= 0x10;
    f.seekp(at);
    f.write(&c, 1);
  }
  bool unusable = false;
  EXPECT_FALSE(cache.load("k", "m", &unusable).has_value());
  EXPECT_TRUE(unusable);
  const Mesh again = cache.get_or_build("k", "m", build, &outcome);
  EXPECT_EQ(outcome, MeshCacheOutcome::kReplaced);
  EXPECT_EQ(builds, 2);
  expect_identical(mesh, again);
  EXPECT_TRUE(cache.load("k", "m").has_value());  // the replacement is whole

  fs::resize_file(path, size - 5);  // torn
  EXPECT_FALSE(cache.load("k", "m", &unusable).has_value());
  EXPECT_TRUE(unusable);
  // Another key's material under this name (a hash collision): a miss, never its mesh.
  cache.store("k", "m", mesh);
  EXPECT_FALSE(cache.load("k", "other material", &unusable).has_value());
  EXPECT_TRUE(unusable);
}

TEST(MeshCache, EvictsLeastRecentlyUsedByBytes) {
  ScratchDir dir;
  const Mesh mesh = make_rectangle_mesh(1.0, 1.0, 10, 10);
  const MeshCache probe(dir.str() + "/probe", 1 << 20);
  probe.store("x", "m", mesh);
  const auto entry_bytes = fs::file_size(probe.entry_path("x"));

  const MeshCache cache(dir.str() + "/c", 3 * entry_bytes);  // room for three
  const auto now = fs::file_time_type::clock::now();
  const std::string keys[] = {"k0", "k1", "k2"};
  for (int i = 0; i < 3; ++i) {
    cache.store(keys[i], "m", mesh);
    fs::last_write_time(cache.entry_path(keys[i]),
                        now - std::chrono::minutes(10 - i));  // k0 oldest
  }
  ASSERT_TRUE(cache.load("k0", "m").has_value());  // a hit makes k0 the newest
  cache.store("k3", "m", mesh);
  EXPECT_TRUE(fs::exists(cache.entry_path("k0")));
  EXPECT_FALSE(fs::exists(cache.entry_path("k1")));  // least recently used
  EXPECT_TRUE(fs::exists(cache.entry_path("k2")));
  EXPECT_TRUE(fs::exists(cache.entry_path("k3")));

  // Temporary files of killed writers go once stale, not while a writer may still use them.
  const std::string stale = cache.entry_path("k9") + ".tmp.1.0";
  const std::string live = cache.entry_path("k8") + ".tmp.2.0";
  std::ofstream(stale) << "x";
  std::ofstream(live) << "x";
  fs::last_write_time(stale, now - std::chrono::hours(2));
  cache.evict();
  EXPECT_FALSE(fs::exists(stale));
  EXPECT_TRUE(fs::exists(live));

  // An entry larger than the whole bound is not stored.
  const MeshCache tiny(dir.str() + "/tiny", entry_bytes / 2);
  tiny.store("k", "m", mesh);
  EXPECT_FALSE(fs::exists(tiny.entry_path("k")));
}

TEST(MeshCache, ConcurrentBuildersBuildOnce) {
  ScratchDir dir;
  const Mesh mesh = make_rectangle_mesh(1.0, 1.0, 20, 20);
  std::atomic<int> builds{0};
  std::vector<Mesh> got(8);
  std::vector<std::thread> threads;
  for (std::size_t t = 0; t < got.size(); ++t) {
    threads.emplace_back([&, t] {
      const MeshCache cache(dir.str(), 1 << 20);  // each worker its own object, as processes
      got[t] = cache.get_or_build("k", "m", [&] {
        ++builds;
        std::this_thread::sleep_for(std::chrono::milliseconds(50));  // others arrive meanwhile
        return mesh;
      });
    });
  }
  for (auto& t : threads) t.join();
  EXPECT_EQ(builds.load(), 1);
  for (const Mesh& m : got) expect_identical(mesh, m);
}

TEST(MeshCache, ReadersNeverSeeAPartialEntry) {
  ScratchDir dir;
  const MeshCache cache(dir.str(), 64 << 20);
  const Mesh mesh = make_rectangle_mesh(1.0, 1.0, 60, 60);
  cache.store("k", "m", mesh);  // readers then always find an entry, never a missing file
  std::atomic<bool> stop{false};
  std::atomic<int> unusable_seen{0}, hits{0};
  std::vector<std::thread> threads;
  for (int w = 0; w < 2; ++w) {
    threads.emplace_back([&] {
      while (!stop) cache.store("k", "m", mesh);  // replaces the entry over and over
    });
  }
  for (int r = 0; r < 2; ++r) {
    threads.emplace_back([&] {
      for (int i = 0; i < 200; ++i) {
        bool unusable = false;
        const auto m = cache.load("k", "m", &unusable);
        if (unusable) ++unusable_seen;
        EXPECT_TRUE(m.has_value());  // replaced by rename: never absent, never partial
        if (m) {
          ++hits;
          EXPECT_TRUE(same_bytes(m->x, mesh.x));
        }
      }
    });
  }
  for (std::size_t i = 2; i < threads.size(); ++i) threads[i].join();
  stop = true;
  threads[0].join();
  threads[1].join();
  EXPECT_EQ(unusable_seen.load(), 0);
  EXPECT_GT(hits.load(), 0);
}

TEST(MeshCache, KillDuringStoreLeavesNoPartialEntry) {
  ScratchDir dir;
  const Mesh mesh = make_rectangle_mesh(1.0, 1.0, 150, 150);  // ~1 MB entries
  for (int round = 0; round < 3; ++round) {
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      const MeshCache cache(dir.str(), 64 << 20);
      const std::string keys[] = {"k0", "k1", "k2"};
      for (int i = 0;; ++i) cache.store(keys[i % 3], "m", mesh);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(30 + 20 * round));
    ::kill(child, SIGKILL);
    int status = 0;
    ::waitpid(child, &status, 0);
    const MeshCache cache(dir.str(), 64 << 20);
    for (const std::string k : {"k0", "k1", "k2"}) {
      bool unusable = false;
      const auto m = cache.load(k, "m", &unusable);
      EXPECT_FALSE(unusable) << "round " << round << " key " << k;
      if (m) expect_identical(mesh, *m);
    }
  }
}

// In a fresh process (the death-test child re-runs only this test): a hit reads the mesh
// without mapping libgmsh; a miss loads it.
TEST(MeshCacheDeathTest, HitDoesNotLoadGmsh) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  ScratchDir dir;
  EXPECT_EXIT(
      {
        const MeshCache cache(dir.str(), 64 << 20);
        const auto spec = normalize_spec(
            parse_spec_json(R"({"geometry": {"disk": {"radius": 1e-3}, "target_elements": 300,
                                "mesher": "FRONTAL_DELAUNAY", "rim_roughness": {"amplitude": 0}}})"));
        const auto material = mesh_key_material(spec.geometry());
        Mesh stand_in = make_rectangle_mesh(1e-3, 1e-3, 4, 4);
        cache.store(mesh_cache_key(*material), *material, stand_in);
        MeshingReport report;
        const Problem p = make_problem(spec, {}, &cache, &report);
        const bool hit_without_gmsh = report.cache == MeshCacheOutcome::kHit &&
                                      p.mesh.x == stand_in.x && !gmsh_mesher_loaded();
        (void)mesh_disk(1e-3, 200);  // a miss does load it (the check above can fail)
        std::error_code ignored;
        fs::remove_all(dir.str(), ignored);  // the child's own folder; its destructor never runs
        std::exit(hit_without_gmsh && gmsh_mesher_loaded() ? 0 : 1);
      },
      ::testing::ExitedWithCode(0), "");
}

}  // namespace
}  // namespace softshock
