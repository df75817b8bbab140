// A daemon shared by several users, over loopback gRPC (issue 35): every job, grid and mesh shows
// its owner and is filterable by it; a user cancels and deletes only their own (PERMISSION_DENIED
// naming the rule), an admin anything; the per-user queue and mesh quotas answer
// RESOURCE_EXHAUSTED naming the bound; the mesh-in-use check sees through "uploads/./ID.msh";
// list pages stay within ~1 MiB whatever their jobs carry.
#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <set>
#include <tuple>

#include "daemon_fixture.hpp"

namespace softshock::server {
namespace {

namespace fs = std::filesystem;
using grpc::StatusCode;
using namespace std::chrono_literals;

const std::string kAlice(40, 'a'), kBob(40, 'b'), kRoot(40, 'r');

v1::RunSpec tiny_spec() {
  v1::RunSpec spec;
  spec.mutable_geometry()->set_target_elements(200);
  spec.mutable_run()->set_end_time(5e-9);
  spec.mutable_run()->set_output_interval(2.5e-9);
  return spec;
}

// Keeps the one worker busy for a minute unless cancelled.
v1::RunSpec long_spec() {
  v1::RunSpec spec;
  spec.mutable_geometry()->set_target_elements(8000);
  spec.mutable_run()->set_end_time(1e-5);
  spec.mutable_run()->set_output_interval(1e-6);
  spec.mutable_run()->set_history_interval(1e-8);
  return spec;
}

std::string square_msh() {
  return "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n"
         "$Nodes\n4\n1 0 0 0\n2 1e-4 0 0\n3 1e-4 1e-4 0\n4 0 1e-4 0\n$EndNodes\n"
         "$Elements\n2\n1 2 2 0 1 1 2 3\n2 2 2 0 1 1 3 4\n$EndElements\n";
}

class UsersServiceTest : public testing::DaemonFixture {
 protected:
  UsersServiceTest() : DaemonFixture("users") {}

  void start_shared(DaemonConfig c = config()) {
    std::filesystem::create_directories(dir_);
    const fs::path users = dir_ / "users";
    std::ofstream(users) << "alice:" << kAlice << "\nbob:" << kBob << "\nroot:" << kRoot
                         << ":admin\n";
    fs::permissions(users, fs::perms::owner_read | fs::perms::owner_write);
    c.users_file = users.string();
    start(c);
    meshes_ = v1::MeshService::NewStub(grpc::CreateChannel(
        "127.0.0.1:" + std::to_string(daemon_->port()), grpc::InsecureChannelCredentials()));
  }
  static std::unique_ptr<grpc::ClientContext> as(const std::string& token) {
    auto c = ctx();
    c->AddMetadata("authorization", "Bearer " + token);
    return c;
  }
  v1::Job submit(const std::string& token, const v1::RunSpec& spec, grpc::Status* status = nullptr,
                 std::map<std::string, std::string> labels = {}) {
    v1::SubmitJobRequest req;
    *req.mutable_spec() = spec;
    req.mutable_labels()->insert(labels.begin(), labels.end());
    v1::Job job;
    const grpc::Status s = stub_->SubmitJob(as(token).get(), req, &job);
    if (status) {
      *status = s;
    } else {
      EXPECT_TRUE(s.ok()) << s.error_message();
    }
    return job;
  }
  grpc::Status cancel(const std::string& token, const std::string& id) {
    v1::CancelJobRequest req;
    req.set_name("jobs/" + id);
    v1::Job job;
    return stub_->CancelJob(as(token).get(), req, &job);
  }
  grpc::Status erase(const std::string& token, const std::string& id) {
    v1::DeleteJobRequest req;
    req.set_name("jobs/" + id);
    v1::DeleteJobResponse resp;
    return stub_->DeleteJob(as(token).get(), req, &resp);
  }
  v1::Job get(const std::string& token, const std::string& id) {
    v1::GetJobRequest req;
    req.set_name(id);
    v1::Job job;
    EXPECT_TRUE(stub_->GetJob(as(token).get(), req, &job).ok());
    return job;
  }
  v1::Job wait_done(const std::string& id) {
    for (auto deadline = std::chrono::steady_clock::now() + 60s;
         std::chrono::steady_clock::now() < deadline;) {
      v1::Job job = get(kRoot, id);
      if (job.state() >= v1::SUCCEEDED) return job;
      std::this_thread::sleep_for(50ms);
    }
    return get(kRoot, id);
  }
  void wait_running(const std::string& id) {
    for (auto deadline = std::chrono::steady_clock::now() + 60s;
         std::chrono::steady_clock::now() < deadline;) {
      if (get(kRoot, id).state() == v1::RUNNING) return;
      std::this_thread::sleep_for(20ms);
    }
    FAIL() << id << " never ran";
  }
  v1::Mesh upload(const std::string& token, const std::string& bytes, grpc::Status* status) {
    v1::Mesh mesh;
    auto c = as(token);
    auto writer = meshes_->UploadMesh(c.get(), &mesh);
    v1::UploadMeshRequest part;
    part.set_file_name("square.msh");
    part.set_data(bytes);
    writer->Write(part);
    writer->WritesDone();
    *status = writer->Finish();
    return mesh;
  }

  std::unique_ptr<v1::MeshService::Stub> meshes_;
};

TEST_F(UsersServiceTest, OwnersShowAndOnlyOwnersOrAdminsCancelOrDelete) {
  start_shared();
  for (const auto& [token, user, role] :
       {std::tuple{kAlice, "alice", "user"}, {kBob, "bob", "user"}, {kRoot, "root", "admin"}}) {
    v1::Caller caller;
    ASSERT_TRUE(stub_->GetCaller(as(token).get(), v1::GetCallerRequest(), &caller).ok());
    EXPECT_EQ(caller.user(), user);
    EXPECT_EQ(caller.role(), role);
  }
  const v1::Job a = submit(kAlice, tiny_spec());
  EXPECT_EQ(a.owner(), "alice");
  const v1::Job b = submit(kBob, tiny_spec());
  EXPECT_EQ(get(kBob, a.id()).owner(), "alice") << "everyone sees everything";

  for (const grpc::Status& s : {cancel(kBob, a.id()), erase(kBob, a.id())}) {
    EXPECT_EQ(s.error_code(), StatusCode::PERMISSION_DENIED) << s.error_message();
    EXPECT_NE(s.error_message().find("jobs/" + a.id() + " is owned by alice: bob may"),
              std::string::npos)
        << s.error_message();
  }
  EXPECT_TRUE(get(kAlice, a.id()).state() != v1::CANCELLED) << "the refusal changed nothing";

  v1::ListJobsRequest list;
  list.set_owner("alice");
  v1::ListJobsResponse page;
  ASSERT_TRUE(stub_->ListJobs(as(kBob).get(), list, &page).ok());
  ASSERT_EQ(page.jobs_size(), 1);
  EXPECT_EQ(page.jobs(0).id(), a.id());
  list.set_owner("no such user!");
  EXPECT_EQ(stub_->ListJobs(as(kBob).get(), list, &page).error_code(),
            StatusCode::INVALID_ARGUMENT);

  wait_done(a.id());
  wait_done(b.id());
  EXPECT_TRUE(erase(kAlice, a.id()).ok()) << "the owner may";
  EXPECT_TRUE(erase(kRoot, b.id()).ok()) << "an admin may";
}

TEST_F(UsersServiceTest, GridsAndMeshesHaveOwnersToo) {
  DaemonConfig c = config();
  start_shared(c);
  v1::SubmitGridRequest grid_req;
  *grid_req.mutable_base_spec() = tiny_spec();
  auto* axis = grid_req.add_axes();
  axis->set_name("pbar");
  axis->add_values(0.5);
  axis->add_values(0.6);
  v1::Grid grid;
  ASSERT_TRUE(stub_->SubmitGrid(as(kAlice).get(), grid_req, &grid).ok());
  EXPECT_EQ(grid.owner(), "alice");
  v1::CancelGridRequest cancel_grid;
  cancel_grid.set_name(grid.name());
  v1::Grid after;
  const grpc::Status refused = stub_->CancelGrid(as(kBob).get(), cancel_grid, &after);
  EXPECT_EQ(refused.error_code(), StatusCode::PERMISSION_DENIED) << refused.error_message();
  v1::ListGridsRequest grids;
  grids.set_owner("bob");
  v1::ListGridsResponse none;
  ASSERT_TRUE(stub_->ListGrids(as(kBob).get(), grids, &none).ok());
  EXPECT_EQ(none.grids_size(), 0);
  grids.set_owner("alice");
  ASSERT_TRUE(stub_->ListGrids(as(kBob).get(), grids, &none).ok());
  EXPECT_EQ(none.grids_size(), 1);
  v1::ListJobsRequest points;
  points.set_owner("alice");
  v1::ListJobsResponse point_page;
  ASSERT_TRUE(stub_->ListJobs(as(kRoot).get(), points, &point_page).ok());
  EXPECT_EQ(point_page.jobs_size(), 2) << "a grid's points belong to the grid's owner";

  grpc::Status s;
  const v1::Mesh mesh = upload(kAlice, square_msh(), &s);
  ASSERT_TRUE(s.ok()) << s.error_message();
  EXPECT_EQ(mesh.owner(), "alice");
  EXPECT_EQ(upload(kBob, square_msh(), &s).owner(), "alice") << "the same bytes, the same mesh";
  v1::DeleteMeshRequest del;
  del.set_name(mesh.name());
  v1::DeleteMeshResponse deleted;
  s = meshes_->DeleteMesh(as(kBob).get(), del, &deleted);
  EXPECT_EQ(s.error_code(), StatusCode::PERMISSION_DENIED) << s.error_message();
  v1::ListMeshesRequest mine;
  mine.set_owner("bob");
  v1::ListMeshesResponse list;
  ASSERT_TRUE(meshes_->ListMeshes(as(kBob).get(), mine, &list).ok());
  EXPECT_EQ(list.meshes_size(), 0);
  mine.set_owner("alice");
  ASSERT_TRUE(meshes_->ListMeshes(as(kBob).get(), mine, &list).ok());
  ASSERT_EQ(list.meshes_size(), 1);
  EXPECT_EQ(list.meshes(0).owner(), "alice");
  EXPECT_TRUE(meshes_->DeleteMesh(as(kRoot).get(), del, &deleted).ok()) << "an admin may";
}

TEST_F(UsersServiceTest, QuotasPerUserAndTheMeshInUseWhateverItsSpelling) {
  DaemonConfig c = config();  // one worker
  c.quotas.max_queued_per_user = 2;
  c.quotas.max_meshes_per_user = 1;
  start_shared(c);
  const v1::Job busy = submit(kRoot, long_spec());
  wait_running(busy.id());

  grpc::Status s;
  const v1::Mesh mesh = upload(kAlice, square_msh(), &s);
  ASSERT_TRUE(s.ok()) << s.error_message();
  upload(kAlice, square_msh() + "\n", &s);
  EXPECT_EQ(s.error_code(), StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(s.error_message().find("max-meshes-per-user = 1"), std::string::npos)
      << s.error_message();

  // A queued job names the mesh by another spelling of its path.
  v1::RunSpec on_mesh = tiny_spec();
  on_mesh.mutable_geometry()->set_mesh_file("uploads/./" + mesh.id() + ".msh");
  const v1::Job queued = submit(kAlice, on_mesh);
  v1::DeleteMeshRequest del;
  del.set_name(mesh.name());
  v1::DeleteMeshResponse deleted;
  s = meshes_->DeleteMesh(as(kAlice).get(), del, &deleted);
  EXPECT_EQ(s.error_code(), StatusCode::FAILED_PRECONDITION) << s.error_message();
  EXPECT_NE(s.error_message().find("jobs/" + queued.id()), std::string::npos) << s.error_message();

  submit(kAlice, tiny_spec());
  submit(kAlice, tiny_spec(), &s);
  EXPECT_EQ(s.error_code(), StatusCode::RESOURCE_EXHAUSTED);
  EXPECT_NE(s.error_message().find("user alice has 2 job(s) queued; 1 more would pass "
                                   "max-queued-per-user = 2"),
            std::string::npos)
      << s.error_message();
  v1::SubmitGridRequest grid;
  *grid.mutable_base_spec() = tiny_spec();
  grid.add_axes()->set_name("pbar");
  grid.mutable_axes(0)->add_values(0.7);
  v1::Grid g;
  s = stub_->SubmitGrid(as(kAlice).get(), grid, &g);
  EXPECT_EQ(s.error_code(), StatusCode::RESOURCE_EXHAUSTED) << s.error_message();
  submit(kBob, tiny_spec(), &s);
  EXPECT_TRUE(s.ok()) << "bob has his own bound: " << s.error_message();

  EXPECT_TRUE(cancel(kAlice, queued.id()).ok());
  EXPECT_TRUE(meshes_->DeleteMesh(as(kAlice).get(), del, &deleted).ok());
  EXPECT_TRUE(cancel(kRoot, busy.id()).ok());
}

TEST_F(UsersServiceTest, ListPagesStayWithinAMebibyte) {
  DaemonConfig c = config();
  start_shared(c);
  // Jobs that carry ~17 kB of labels each: 100 of them are 1.7 MB.
  std::map<std::string, std::string> labels;
  for (int i = 0; i < 64; ++i) {
    std::string key = "k";  // appended: GCC 12's -Wrestrict misfires on "k" + to_string(i)
    key += std::to_string(i);
    labels[key] = std::string(255, 'v');
  }
  std::set<std::string> ids;
  v1::RunSpec quick = tiny_spec();
  for (int i = 0; i < 100; ++i) {
    v1::SubmitJobRequest req;
    *req.mutable_spec() = quick;
    req.mutable_labels()->insert(labels.begin(), labels.end());
    req.set_reuse_result(true);  // no need to run them all
    v1::Job job;
    ASSERT_TRUE(stub_->SubmitJob(as(kAlice).get(), req, &job).ok());
    ids.insert(job.id());
  }
  v1::ListJobsRequest list;
  list.set_page_size(1000);
  std::set<std::string> seen;
  int pages = 0;
  for (;;) {
    v1::ListJobsResponse page;
    ASSERT_TRUE(stub_->ListJobs(as(kBob).get(), list, &page).ok());
    ++pages;
    EXPECT_LE(page.ByteSizeLong(), (1u << 20) + 20'000u);
    for (const auto& j : page.jobs()) seen.insert(j.id());
    if (page.next_page_token().empty()) break;
    list.set_page_token(page.next_page_token());
  }
  EXPECT_EQ(seen, ids);
  EXPECT_GE(pages, 2);
}

}  // namespace
}  // namespace softshock::server
