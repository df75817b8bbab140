// Uploaded meshes and their users (issue 35): every mesh records its uploader, survives a reopen
// with it (records from before owners read as the default user's), counts against per-user and
// global quotas checked with the id known (so re-sending a stored mesh always works), lists by
// owner; and a mesh is "in use" when a queued or running job's mesh_file resolves to it, however
// the path is spelt.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <random>

#include "server/jobs/mesh_process.hpp"
#include "server/store/catalogue.hpp"
#include "server/store/mesh_store.hpp"
#include "server/store/resource_exhausted.hpp"

namespace softshock::server {
namespace {

namespace fs = std::filesystem;

// Two triangles on a 100 µm square (MSH 2.2); `comment` makes other bytes of the same mesh.
std::string square(const std::string& comment = "") {
  return "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n"
         "$Nodes\n4\n1 0 0 0\n2 1e-4 0 0\n3 1e-4 1e-4 0\n4 0 1e-4 0\n$EndNodes\n"
         "$Elements\n2\n1 2 2 0 1 1 2 3\n2 2 2 0 1 1 3 4\n$EndElements\n" +
         comment;
}

class MeshOwnersTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("softshock-mesh-owners-" + std::to_string(std::random_device{}()));
  }
  void TearDown() override { fs::remove_all(dir_); }
  MeshStore store(QuotaLimits quotas = {}) {
    MeshStoreLimits limits;
    limits.max_elements = 1000;
    limits.quotas = quotas;
    return MeshStore((dir_ / "meshes").string(), limits,
                     mesh_validator_in_child(find_mesher(), {}));
  }
  static std::string exhausted(const std::function<void()>& f) {
    try {
      f();
    } catch (const ResourceExhausted& e) {
      return e.what();
    }
    return "";
  }
  fs::path dir_;
};

TEST_F(MeshOwnersTest, UploadsRecordTheirOwnerAcrossReopen) {
  std::string a, b;
  {
    MeshStore s = store();
    a = s.add(square(), "a.msh", 1, "alice").id();
    b = s.add(square("\n"), "b.msh", 2, "bob").id();
    EXPECT_EQ(s.get(a)->owner(), "alice");
    // The same bytes from someone else are the same mesh, still the first uploader's.
    EXPECT_EQ(s.add(square(), "mine.msh", 3, "bob").owner(), "alice");
  }
  // A record from before owners existed.
  const fs::path old_record = dir_ / "meshes" / "uploads" / (b + ".json");
  std::string text;
  {
    std::ifstream in(old_record);
    text.assign(std::istreambuf_iterator<char>(in), {});
  }
  const auto at = text.find(",\"owner\":\"bob\"");
  ASSERT_NE(at, std::string::npos) << text;
  text.erase(at, std::string(",\"owner\":\"bob\"").size());
  std::ofstream(old_record) << text;

  MeshStore s = store();
  EXPECT_EQ(s.get(a)->owner(), "alice");
  EXPECT_EQ(s.get(b)->owner(), "default");
  EXPECT_EQ(s.usage("alice").count, 1);
  EXPECT_EQ(s.usage("default").count, 1);
  ASSERT_EQ(s.list("", 10, "alice").size(), 1u);
  EXPECT_EQ(s.list("", 10, "alice")[0].id(), a);
  EXPECT_EQ(s.list("", 10, "default")[0].id(), b);
  EXPECT_TRUE(s.list("", 10, "carol").empty());
  EXPECT_EQ(s.list("", 10).size(), 2u);
}

TEST_F(MeshOwnersTest, QuotasPerUserAndInAll) {
  QuotaLimits q;
  q.max_meshes_per_user = 2;
  q.max_meshes = 3;
  q.max_mesh_bytes_per_user = 1 << 20;
  q.max_mesh_bytes = 4 << 20;
  MeshStore s = store(q);
  const std::string first = s.add(square("%1\n"), "1.msh", 1, "alice").id();
  s.add(square("%2\n"), "2.msh", 1, "alice");
  const std::string third = exhausted([&] { s.add(square("%3\n"), "3.msh", 1, "alice"); });
  EXPECT_NE(third.find("user alice stores 2 mesh(es), the most max-meshes-per-user = 2 allows"),
            std::string::npos)
      << third;
  EXPECT_EQ(s.add(square("%1\n"), "again.msh", 2, "alice").id(), first)
      << "re-sending a stored mesh is not a new one";
  EXPECT_EQ(s.usage("alice").count, 2);
  s.add(square("%4\n"), "4.msh", 1, "bob");  // bob has his own two
  const std::string all = exhausted([&] { s.add(square("%5\n"), "5.msh", 1, "bob"); });
  EXPECT_NE(all.find("the daemon stores 3 uploaded mesh(es), the most max-meshes = 3 allows"),
            std::string::npos)
      << all;
  EXPECT_TRUE(s.remove(first));  // room again
  EXPECT_EQ(s.usage("").count, 2);
  s.add(square("%5\n"), "5.msh", 1, "bob");

  // Bytes: a mesh that would take a user past theirs.
  QuotaLimits small;
  small.max_mesh_bytes_per_user = static_cast<std::int64_t>(square().size() * 2 + 10);
  fs::remove_all(dir_);
  MeshStore t = store(small);
  t.add(square("%a\n"), "a.msh", 1, "carol");
  t.add(square("%b\n"), "b.msh", 1, "carol");
  const std::string bytes = exhausted([&] { t.add(square("%c\n"), "c.msh", 1, "carol"); });
  EXPECT_NE(bytes.find("would pass max-mesh-bytes-per-user"), std::string::npos) << bytes;
  std::size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir_ / "meshes" / "uploads")) {
    (void)e;
    ++files;
  }
  EXPECT_EQ(files, 4u) << "two meshes, two records; the refused upload's staged file is gone";
}

TEST_F(MeshOwnersTest, InUseComparesWhatTheMeshFileResolvesTo) {
  MeshStore s = store();
  const std::string id = s.add(square(), "a.msh", 1, "alice").id();
  const std::string other = s.add(square("\n"), "b.msh", 1, "alice").id();
  fs::create_directories(dir_ / "meshes" / "links");
  fs::create_symlink("../uploads/" + id + ".msh", dir_ / "meshes" / "links" / "alias.msh");
  Catalogue c((dir_ / "catalogue.sqlite").string(), 0);
  auto add_job = [&](const std::string& job_id, const std::string& mesh_file) {
    NewJob j;
    j.id = job_id;
    j.spec_json = R"({"geometry":{"mesh_file":")" + mesh_file + R"("},"run":{"end_time":1e-9}})";
    j.spec_hash = job_id;
    j.create_us = now_us();
    j.owner = "bob";
    c.insert(j);
  };
  EXPECT_FALSE(job_using_mesh(c, s, id));
  add_job("uses-other", "uploads/" + other + ".msh");
  add_job("missing", "studies/gone.msh");
  EXPECT_FALSE(job_using_mesh(c, s, id));
  // Each spelling alone is found: the text search of old let all but the first through.
  int n = 0;
  for (const std::string& spelling :
       {"uploads/" + id + ".msh", "uploads/./" + id + ".msh", "uploads//" + id + ".msh",
        "./uploads/" + id + ".msh", std::string("links/alias.msh")}) {
    std::string job_id = "spelling";
    job_id += std::to_string(n++);
    add_job(job_id, spelling);
    auto user = job_using_mesh(c, s, id);
    EXPECT_EQ(user.value_or("none"), job_id) << spelling;
    ASSERT_TRUE(c.cancel_queued(job_id, now_us()));  // finished jobs do not hold a mesh
    EXPECT_FALSE(job_using_mesh(c, s, id)) << spelling;
  }
  add_job("running", "uploads/./" + id + ".msh");
  ASSERT_TRUE(c.start("running", now_us()));
  EXPECT_EQ(job_using_mesh(c, s, id).value_or("none"), "running");
}

}  // namespace
}  // namespace softshock::server
