// Uploaded meshes: content addressing, idempotence, the size and element caps, validation with
// the mesh-file reader, listing by id, removal; and how the daemon resolves geometry.mesh_id.
#include <gtest/gtest.h>

#include <filesystem>
#include <functional>
#include <random>

#include "server/store/mesh_store.hpp"
#include "server/store/spec_hash.hpp"

namespace softshock::server {
namespace {

namespace fs = std::filesystem;

// Two triangles on a 100 µm square, MSH 2.2 (a format Gmsh and our reader accept).
std::string square_msh(const std::string& comment = "") {
  return "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n"
         "$Nodes\n4\n1 0 0 0\n2 1e-4 0 0\n3 1e-4 1e-4 0\n4 0 1e-4 0\n$EndNodes\n"
         "$Elements\n2\n1 2 2 0 1 1 2 3\n2 2 2 0 1 1 3 4\n$EndElements\n" +
         comment;
}

class MeshStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ =
        fs::temp_directory_path() / ("softshock-meshes-" + std::to_string(std::random_device{}()));
  }
  void TearDown() override { fs::remove_all(dir_); }
  MeshStore store(int64_t max_bytes = 1 << 20, int64_t max_elements = 1000) {
    return MeshStore((dir_ / "meshes").string(), max_bytes, max_elements);
  }
  std::string rule_of(const std::function<void()>& f) {
    try {
      f();
    } catch (const SpecError& e) {
      return e.what();
    }
    return "no SpecError";
  }
  fs::path dir_;
};

TEST_F(MeshStoreTest, SameBytesSameIdStoredOnce) {
  MeshStore s = store();
  const std::string bytes = square_msh();
  const v1::Mesh m = s.add(bytes, "/home/u/square.msh", 1000);
  EXPECT_EQ(m.id(), sha256_hex(bytes));
  EXPECT_EQ(m.name(), "meshes/" + m.id());
  EXPECT_EQ(m.nodes(), 4);
  EXPECT_EQ(m.elements(), 2);
  EXPECT_EQ(m.size_bytes(), static_cast<int64_t>(bytes.size()));
  EXPECT_EQ(m.file_name(), "square.msh");
  EXPECT_EQ(uploaded_mesh_file(m.id()), "uploads/" + m.id() + ".msh");
  EXPECT_TRUE(fs::is_regular_file(dir_ / "meshes" / uploaded_mesh_file(m.id())));
  const v1::Mesh again = s.add(bytes, "other.msh", 2000);  // idempotent: the first record
  EXPECT_EQ(again.SerializeAsString(), m.SerializeAsString());
}

TEST_F(MeshStoreTest, CapsAndValidationNameTheDataField) {
  const std::string bytes = square_msh();
  MeshStore small = store(static_cast<int64_t>(bytes.size()) - 1);
  EXPECT_NE(
      rule_of([&] { small.add(bytes, "a.msh", 0); }).find("data: the mesh file has more than"),
      std::string::npos);
  MeshStore s = store(1 << 20, 1);
  EXPECT_EQ(rule_of([&] { s.add("", "a.msh", 0); }), "data: the mesh file is empty");
  EXPECT_EQ(rule_of([&] { s.add(bytes, "a.msh", 0); }),
            "data: the mesh has 2 elements, more than 1");
  const std::string garbage = rule_of([&] { s.add("hello", "mine.msh", 0); });
  EXPECT_EQ(garbage.rfind("data: not a usable Gmsh mesh", 0), 0u) << garbage;
  EXPECT_NE(garbage.find("mine.msh"), std::string::npos) << garbage;
  EXPECT_EQ(garbage.find(".staged-"), std::string::npos) << garbage;
  EXPECT_TRUE(s.list("", 10).empty());
  EXPECT_TRUE(fs::is_empty(dir_ / "meshes" / "uploads"));  // nothing staged is left behind
}

TEST_F(MeshStoreTest, ListsByIdInPagesAndRemoves) {
  MeshStore s = store();
  std::string a = s.add(square_msh(), "a.msh", 1).id(),
              b = s.add(square_msh("\n"), "b.msh", 2).id();
  if (b < a) std::swap(a, b);
  ASSERT_NE(a, b);
  auto first = s.list("", 1);
  ASSERT_EQ(first.size(), 1u);
  EXPECT_EQ(first[0].id(), a);
  auto rest = s.list(a, 10);
  ASSERT_EQ(rest.size(), 1u);
  EXPECT_EQ(rest[0].id(), b);
  EXPECT_TRUE(s.remove(a));
  EXPECT_FALSE(s.get(a));
  EXPECT_FALSE(s.remove(a));
  EXPECT_FALSE(s.remove("../../etc/passwd"));
  EXPECT_EQ(s.list("", 10).size(), 1u);
}

TEST_F(MeshStoreTest, MeshIdResolvesToTheUploadedFile) {
  MeshStore s = store();
  SpecLimits limits;  // as the daemon's: mesh_file resolved under DATA/meshes/ only
  limits.mesh_root = s.meshes_dir();
  const std::string id = s.add(square_msh(), "a.msh", 1).id();
  v1::RunSpec by_id;
  by_id.mutable_geometry()->set_mesh_id("meshes/" + id);
  const CanonicalSpec c = daemon_canonical_spec(by_id, limits, s);
  EXPECT_EQ(c.spec.geometry().mesh_file(), "uploads/" + id + ".msh");
  EXPECT_TRUE(c.spec.geometry().mesh_id().empty());
  v1::RunSpec by_file;  // the same run named by its file: the same job for dedup
  by_file.mutable_geometry()->set_mesh_file("uploads/" + id + ".msh");
  EXPECT_EQ(daemon_canonical_spec(by_file, limits, s).hash, c.hash);

  v1::RunSpec both = by_id;
  both.mutable_geometry()->mutable_disk()->set_radius(1e-4);
  EXPECT_EQ(rule_of([&] { daemon_canonical_spec(both, limits, s); }),
            "geometry.mesh_id: cannot be combined with geometry.disk, rounded_square or mesh_file");
  v1::RunSpec unknown;
  unknown.mutable_geometry()->set_mesh_id(std::string(64, 'a'));
  EXPECT_EQ(rule_of([&] {
              daemon_canonical_spec(unknown, limits, s);
            }).rfind("geometry.mesh_id: no uploaded mesh", 0),
            0u);
  v1::RunSpec missing;  // one text for absent and not allowed, never the server's path
  missing.mutable_geometry()->set_mesh_file("studies/none.msh");
  const std::string rule = rule_of([&] { daemon_canonical_spec(missing, limits, s); });
  EXPECT_NE(rule.find("names no mesh file in the daemon's meshes folder"), std::string::npos)
      << rule;
  EXPECT_EQ(rule.find(dir_.string()), std::string::npos) << rule;
}

}  // namespace
}  // namespace softshock::server
