// Uploaded meshes: content addressing, idempotence, the size and element caps, validation with
// the mesh-file reader, listing by id, removal; and how the daemon resolves geometry.mesh_id.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <random>

#include "server/jobs/mesh_process.hpp"
#include "server/store/mesh_store.hpp"
#include "server/store/resource_exhausted.hpp"
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
  // As the daemon's: every upload checked by softshock-mesh --check in a confined child.
  MeshStore store(int64_t max_bytes = 1 << 20, int64_t max_elements = 1000,
                  MeshCheckLimits check = {}) {
    MeshStoreLimits limits;
    limits.max_bytes = max_bytes;
    limits.max_elements = max_elements;
    return MeshStore((dir_ / "meshes").string(), limits,
                     mesh_validator_in_child(find_mesher(), check));
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

// FIPS 180-4's examples, and the same digest from parts as from the whole (ids and spec hashes
// stored by earlier releases stay valid).
TEST(Sha256, KnownDigestsWholeOrInParts) {
  EXPECT_EQ(sha256_hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(sha256_hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  const std::string two_blocks = "abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq";
  EXPECT_EQ(sha256_hex(two_blocks),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
  Sha256 parts;
  for (std::size_t at = 0; at < two_blocks.size(); at += 5) parts.update(two_blocks.substr(at, 5));
  EXPECT_EQ(parts.hex_digest(), sha256_hex(two_blocks));
  EXPECT_EQ(parts.hex_digest(), sha256_hex(""));  // starts again, empty
}

TEST_F(MeshStoreTest, SameBytesSameIdStoredOnce) {
  MeshStore s = store();
  const std::string bytes = square_msh();
  const v1::Mesh m = s.add(bytes, "square.msh", 1000);
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
  EXPECT_EQ(garbage.rfind("data: 'mine.msh' is not a usable Gmsh mesh", 0), 0u) << garbage;
  EXPECT_NE(garbage.find("mine.msh"), std::string::npos) << garbage;
  EXPECT_EQ(garbage.find(".staged-"), std::string::npos) << garbage;
  EXPECT_TRUE(s.list("", 10).empty());
  EXPECT_TRUE(fs::is_empty(dir_ / "meshes" / "uploads"));  // nothing staged is left behind
}

// Two triangles on a 100 µm square, MSH 4.1, with one node tag of the second triangle given.
std::string square_msh41(const std::string& node_tag = "4") {
  return "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n"
         "$Nodes\n1 4 1 4\n2 1 0 4\n1\n2\n3\n4\n0 0 0\n1e-4 0 0\n1e-4 1e-4 0\n0 1e-4 0\n"
         "$EndNodes\n$Elements\n1 2 1 2\n2 1 2 2\n1 1 2 3\n2 1 3 " +
         node_tag + "\n$EndElements\n";
}

// What an upload leaves in uploads/ besides the meshes' files and records.
std::vector<std::string> leftovers(const fs::path& uploads) {
  std::vector<std::string> out;
  for (const auto& e : fs::directory_iterator(uploads)) {
    const std::string name = e.path().filename().string();
    if (!(name.size() == 64 + 4 && name.ends_with(".msh")) &&
        !(name.size() == 64 + 5 && name.ends_with(".json"))) {
      out.push_back(name);
    }
  }
  return out;
}

// Gmsh 4.8 segfaults on a node tag of 2^63 - 1 or -1 in an element line (found by a mutation
// fuzzer; in the daemon this killed softshockd). The checker child crashes instead: the upload is
// refused with the reason, nothing is left behind, and the store takes the next upload.
TEST_F(MeshStoreTest, AMeshThatCrashesGmshIsRefusedAndTheStoreGoesOn) {
  MeshStore s = store();
  for (const char* tag : {"9223372036854775807", "-1", "18446744073709551615"}) {
    const std::string rule = rule_of([&] { s.add(square_msh41(tag), "crash.msh", 0); });
    EXPECT_EQ(rule.rfind("data: 'crash.msh' is not a usable Gmsh mesh: Gmsh crashed reading it "
                         "(signal 11",
                         0),
              0u)
        << tag << ": " << rule;
    EXPECT_EQ(rule.find(dir_.string()), std::string::npos) << rule;
  }
  EXPECT_TRUE(leftovers(dir_ / "meshes" / "uploads").empty());
  const v1::Mesh ok = s.add(square_msh41(), "square.msh", 1);
  EXPECT_EQ(ok.elements(), 2);
  EXPECT_EQ(ok.nodes(), 4);
}

// A 161-byte header that declares 1.5e8 nodes made Gmsh allocate 3.2 GB: refused from the
// counts, before Gmsh is loaded.
TEST_F(MeshStoreTest, DeclaredCountsBeyondTheFileAreRefusedBeforeReading) {
  MeshStore s = store();
  const std::string header =
      "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 150000000 1 150000000\n"
      "2 1 0 150000000\n1\n2\n3\n$EndNodes\n";
  const std::string rule = rule_of([&] { s.add(header, "huge.msh", 0); });
  EXPECT_EQ(rule,
            "data: 'huge.msh' is not a usable Gmsh mesh: $Nodes declares 150000000 nodes, more "
            "than a file of " +
                std::to_string(header.size()) + " bytes holds (each takes at least 8 bytes)");
  std::string elements = square_msh41();
  elements.replace(elements.find("1 2 1 2\n"), 8, "1 99999999999 1 2\n");
  EXPECT_NE(
      rule_of([&] { s.add(elements, "e.msh", 0); }).find("$Elements declares 99999999999 elements"),
      std::string::npos);
  EXPECT_TRUE(leftovers(dir_ / "meshes" / "uploads").empty());
}

// The checker runs under the daemon's limits: out of memory or of time it is the upload's
// refusal, never the daemon's failure.
TEST_F(MeshStoreTest, TheCheckerIsConfined) {
  MeshCheckLimits no_time;
  no_time.max_wall_seconds = 0;
  MeshStore s = store(1 << 20, 1000, no_time);
  EXPECT_EQ(rule_of([&] { s.add(square_msh(), "slow.msh", 0); }),
            "data: 'slow.msh' is not a usable Gmsh mesh: checking the mesh took longer than 0 s "
            "(the daemon's limit)");
#ifndef __SANITIZE_ADDRESS__  // the sanitizer build runs the checker without a memory limit
  MeshCheckLimits little_memory;
  little_memory.max_memory_bytes = std::uint64_t{128} << 20;  // Gmsh loads in ~100 MiB
  MeshStore m = store(64 << 20, 1000000, little_memory);
  // 300 x 300 cells, 180,000 triangles: far more than 128 MiB of Gmsh's data.
  std::string big = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n";
  const int n = 300;
  big += std::to_string((n + 1) * (n + 1)) + "\n";
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i)
      big += std::to_string(j * (n + 1) + i + 1) + " " + std::to_string(i * 1e-6) + " " +
             std::to_string(j * 1e-6) + " 0\n";
  big += "$EndNodes\n$Elements\n" + std::to_string(2 * n * n) + "\n";
  int tag = 0;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i + 1, b = a + 1, c = a + n + 2, d = a + n + 1;
      big += std::to_string(++tag) + " 2 2 0 1 " + std::to_string(a) + " " + std::to_string(b) +
             " " + std::to_string(c) + "\n";
      big += std::to_string(++tag) + " 2 2 0 1 " + std::to_string(a) + " " + std::to_string(c) +
             " " + std::to_string(d) + "\n";
    }
  big += "$EndElements\n";
  const std::string rule = rule_of([&] { m.add(big, "big.msh", 0); });
  EXPECT_EQ(rule, "data: 'big.msh' is not a usable Gmsh mesh: reading it needs more than 128 MiB");
#endif
  EXPECT_TRUE(leftovers(dir_ / "meshes" / "uploads").empty());
}

TEST_F(MeshStoreTest, FileNamesArePlainAndBounded) {
  MeshStore s = store();
  const std::string bytes = square_msh();
  for (const std::string& bad :
       {std::string("../../etc/passwd"), std::string("/home/u/a.msh"), std::string("a\\b.msh"),
        std::string("a\0b.msh", 7), std::string("a\nb.msh"), std::string(".."),
        std::string(256, 'a'), std::string()}) {
    const std::string rule = rule_of([&] { s.add(bytes, bad, 0); });
    EXPECT_EQ(rule.rfind("file_name: ", 0), 0u) << rule;
    EXPECT_LT(rule.size(), 200u);  // never echoes the name
  }
  EXPECT_TRUE(s.list("", 10).empty());
  EXPECT_EQ(s.add(bytes, std::string(255, 'a'), 0).file_name(), std::string(255, 'a'));
  EXPECT_EQ(s.add(square_msh("\n"), "gel disk (µm).msh", 0).file_name(), "gel disk (µm).msh");
}

TEST_F(MeshStoreTest, WhatACrashLeftIsSweptWhenTheStoreOpens) {
  std::string id;
  {
    MeshStore s = store();
    id = s.add(square_msh(), "a.msh", 1).id();
  }
  const fs::path uploads = dir_ / "meshes" / "uploads";
  std::ofstream(uploads / ".staged-0123456789abcdef.msh") << "half an upload";
  fs::create_directories(uploads / ".check-0123456789abcdef");
  std::ofstream(uploads / ".check-0123456789abcdef" / "mesh.msh") << "Gmsh's copy";
  std::ofstream(uploads / (std::string(64, 'b') + ".json.tmp")) << "{";
  EXPECT_EQ(leftovers(uploads).size(), 3u);
  MeshStore s = store();
  EXPECT_TRUE(leftovers(uploads).empty());
  EXPECT_TRUE(s.get(id));  // the stored mesh stays
}

TEST_F(MeshStoreTest, ConcurrentUploadsAreBounded) {
  MeshStoreLimits limits;
  limits.max_concurrent_uploads = 2;
  MeshStore s((dir_ / "meshes").string(), limits, mesh_validator_in_child(find_mesher(), {}));
  auto a = s.begin_upload(), b = s.begin_upload();
  EXPECT_THROW(s.begin_upload(), ResourceExhausted);
  a.reset();  // finished (here: abandoned, its staged file removed)
  auto c = s.begin_upload();
  c->append(square_msh());
  EXPECT_EQ(s.commit(*c, "c.msh", kDefaultUser, 0).elements(), 2);
  b.reset(), c.reset();
  EXPECT_TRUE(leftovers(dir_ / "meshes" / "uploads").empty());
}

TEST_F(MeshStoreTest, UploadsKeepTheDiskReserve) {
  double free = 100.0 * (1 << 20);
  MeshStoreLimits limits;
  limits.max_bytes = 64 << 20;
  limits.min_free_bytes = 256.0 * (1 << 20);
  limits.free_bytes = [&](const std::string&) { return free; };
  MeshStore s((dir_ / "meshes").string(), limits, mesh_validator_in_child(find_mesher(), {}));
  try {
    s.begin_upload();
    ADD_FAILURE() << "an upload began below the reserve";
  } catch (const ResourceExhausted& e) {
    EXPECT_EQ(std::string(e.what()),
              "the daemon's disk has 100 MiB free, below its reserve of 256 MiB (delete results "
              "or meshes to make room)");
  }
  free = 300.0 * (1 << 20);
  auto u = s.begin_upload();
  const std::string part(1 << 20, 'x');
  for (int k = 0; k < 3; ++k) u->append(part);
  free = 256.5 * (1 << 20);  // others filled the disk meanwhile: the next MiB would cross it
  EXPECT_THROW(u->append(part), ResourceExhausted);
  u.reset();
  EXPECT_TRUE(leftovers(dir_ / "meshes" / "uploads").empty());
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
