// Who may do what (server/policy/): users files and their rules, the token table, the owner rule,
// the quota messages, the audit line's fields and the log's rate limit.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <thread>

#include "server/log.hpp"
#include "server/policy/ownership.hpp"
#include "server/policy/quotas.hpp"
#include "server/policy/users.hpp"
#include "server/store/resource_exhausted.hpp"

namespace softshock::server {
namespace {

namespace fs = std::filesystem;

const std::string kAlice(40, 'a'), kBob(40, 'b'), kRoot(40, 'r');

class UsersTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ =
        fs::temp_directory_path() / ("softshock-users-" + std::to_string(std::random_device{}()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string file(const std::string& text, const std::string& name = "users",
                   fs::perms mode = fs::perms::owner_read | fs::perms::owner_write) {
    const fs::path p = dir_ / name;
    std::ofstream(p) << text;
    fs::permissions(p, mode);
    return p.string();
  }
  static std::string error_of(const std::function<void()>& f) {
    try {
      f();
    } catch (const std::exception& e) {
      return e.what();
    }
    return "";
  }
  fs::path dir_;
};

TEST_F(UsersTest, UsersFileLinesNameUsersTokensAndRoles) {
  const auto users =
      read_users_file(file("# the lab's users\n\n  alice:" + kAlice + "  \n" + "bob:" + kBob +
                           ":user\nroot.admin:" + kRoot + ":admin\n"));
  ASSERT_EQ(users.size(), 3u);
  EXPECT_EQ(users[0].user, "alice");
  EXPECT_EQ(users[0].token, kAlice);
  EXPECT_EQ(users[0].role, Role::kUser);
  EXPECT_EQ(users[1].role, Role::kUser);
  EXPECT_EQ(users[2].user, "root.admin");
  EXPECT_EQ(users[2].role, Role::kAdmin);
}

TEST_F(UsersTest, UsersFileMistakesAreRefusedByLineWithoutTheToken) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"alice\n", ":1: expected user:token"},
      {"alice:" + kAlice + ":root\n", ":1: role 'root' is neither user nor admin"},
      {"# ok\nalice:short\n", ":2: the token of alice holds 5 bytes; a token needs at least 32"},
      {"alice:" + kAlice + "\nalice:" + kBob + "\n", ":2: user alice is given twice"},
      {"alice:" + kAlice + "\nbob:" + kAlice + "\n", ":2: user bob has the same token as alice"},
      {"al ice:" + kAlice + "\n", ":1: user name 'al ice' must be"},
      {"-x:" + kAlice + "\n", ":1: user name '-x' must be"},
      {"alice:" + kAlice + ":admin:extra\n", ":1: expected user:token"},
      {"alice:" + kAlice.substr(0, 20) + " " + kAlice + "\n", "contains whitespace"},
  };
  for (const auto& [text, expected] : cases) {
    const std::string e = error_of([&] { read_users_file(file(text)); });
    EXPECT_NE(e.find(expected), std::string::npos) << text << " -> " << e;
    EXPECT_EQ(e.find(kAlice), std::string::npos) << "a token in an error message: " << e;
    EXPECT_EQ(e.find(kBob), std::string::npos) << "a token in an error message: " << e;
  }
}

TEST_F(UsersTest, UsersFileMustBePrivateLikeTheTokenFile) {
  const auto owner = fs::perms::owner_read | fs::perms::owner_write;
  for (auto others : {fs::perms::others_read, fs::perms::others_write}) {
    const std::string e =
        error_of([&] { read_users_file(file("alice:" + kAlice + "\n", "users", owner | others)); });
    EXPECT_NE(e.find("accessible to other users"), std::string::npos) << e;
  }
  EXPECT_EQ(
      error_of([&] {
        read_users_file(file("alice:" + kAlice + "\n", "users", owner | fs::perms::group_read));
      }),
      "")
      << "0640: the daemon's group may read it (Kubernetes fsGroup)";
  fs::create_directories(dir_ / "folder");
  EXPECT_NE(error_of([&] { read_users_file((dir_ / "folder").string()); }), "");
}

TEST_F(UsersTest, TheTableFindsTheUserOfATokenAndNothingElse) {
  const UserTable table = load_users(file(kRoot + "\n", "token"), "ops",
                                     file("alice:" + kAlice + "\nbob:" + kBob + ":admin\n"));
  EXPECT_EQ(table.size(), 3u);
  auto root = table.find(kRoot);
  ASSERT_TRUE(root);
  EXPECT_EQ(root->user, "ops");
  EXPECT_TRUE(root->is_admin()) << "the token file's user is an admin, as it always could do all";
  auto alice = table.find(kAlice);
  ASSERT_TRUE(alice);
  EXPECT_EQ(alice->user, "alice");
  EXPECT_FALSE(alice->is_admin());
  EXPECT_TRUE(table.find(kBob)->is_admin());
  for (const std::string& wrong :
       {std::string(), kAlice.substr(1), kAlice + "a", std::string(40, 'x'), "Bearer " + kAlice}) {
    EXPECT_FALSE(table.find(wrong)) << wrong;
  }
  // A users-file line clashing with the token file's user is refused, naming both files.
  const std::string clash = error_of(
      [&] { load_users(file(kRoot + "\n", "token"), "alice", file("alice:" + kAlice + "\n")); });
  EXPECT_NE(clash.find("user alice is given twice"), std::string::npos) << clash;
  EXPECT_TRUE(load_users("", "", "").empty());
  // The single token keeps working as before: the default user.
  EXPECT_EQ(load_users(file(kRoot + "\n", "token"), "", "").find(kRoot)->user, "default");
}

TEST(Ownership, UsersChangeOnlyTheirOwnAdminsAnything) {
  const Caller alice{"alice", Role::kUser}, root{"root", Role::kAdmin};
  EXPECT_TRUE(may_modify(alice, "alice"));
  EXPECT_FALSE(may_modify(alice, "bob"));
  EXPECT_TRUE(may_modify(root, "bob"));
  try {
    require_may_modify(alice, "jobs/0123", "bob", "delete");
    FAIL() << "no PermissionDenied";
  } catch (const PermissionDenied& e) {
    EXPECT_STREQ(e.what(),
                 "jobs/0123 is owned by bob: alice may delete only their own jobs, grids and "
                 "meshes (an admin may delete any)");
  }
}

TEST(Quotas, RefusalsNameTheBoundAndTheWayBelowIt) {
  QuotaLimits q;
  q.max_queued_per_user = 3;
  q.max_meshes_per_user = 2;
  q.max_mesh_bytes_per_user = 10 << 20;
  q.max_meshes = 5;
  q.max_mesh_bytes = 20 << 20;
  auto message = [](const std::function<void()>& f) {
    try {
      f();
    } catch (const ResourceExhausted& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  const std::string queued = message([&] { throw_queued_quota(q, "alice", 3, 2); });
  EXPECT_NE(
      queued.find("user alice has 3 job(s) queued; 2 more would pass max-queued-per-user = 3"),
      std::string::npos)
      << queued;
  EXPECT_NE(queued.find("softshock list --owner alice --state QUEUED"), std::string::npos);
  EXPECT_EQ(message([&] {
              check_mesh_quota(q, "alice", {1, 1 << 20}, {1, 1 << 20}, 1 << 20);
            }),
            "");
  EXPECT_NE(message([&] {
              check_mesh_quota(q, "alice", {2, 2}, {2, 2}, 1);
            }).find("user alice stores 2 mesh(es), the most max-meshes-per-user = 2 allows"),
            std::string::npos);
  EXPECT_NE(message([&] {
              check_mesh_quota(q, "alice", {1, 9 << 20}, {1, 9 << 20}, 2 << 20);
            }).find("would pass max-mesh-bytes-per-user = 10 MiB"),
            std::string::npos);
  EXPECT_NE(message([&] {
              check_mesh_quota(q, "alice", {0, 0}, {5, 5}, 1);
            }).find("the most max-meshes = 5 allows"),
            std::string::npos);
  EXPECT_NE(message([&] {
              check_mesh_quota(q, "alice", {0, 0}, {4, 19 << 20}, 2 << 20);
            }).find("would pass max-mesh-bytes = 20 MiB"),
            std::string::npos);
}

TEST(LogRateLimit, ABurstThenTheRateWithTheDroppedCounted) {
  LogRateLimit limit(3, 0);  // no refill: exactly the burst
  std::int64_t dropped = -1;
  for (int i = 0; i < 3; ++i) {
    EXPECT_TRUE(limit.allow(&dropped));
    EXPECT_EQ(dropped, 0);
  }
  for (int i = 0; i < 1000; ++i) EXPECT_FALSE(limit.allow(&dropped));
  LogRateLimit refilling(1, 200);  // one line per 5 ms
  EXPECT_TRUE(refilling.allow(&dropped));
  for (int i = 0; i < 7; ++i) EXPECT_FALSE(refilling.allow(&dropped));
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_TRUE(refilling.allow(&dropped));
  EXPECT_EQ(dropped, 7) << "the line that passes says how many were dropped";
}

TEST(LogField, PrintableWithoutSpacesAndBounded) {
  EXPECT_EQ(log_field(""), "-");
  EXPECT_EQ(log_field("jobs/0123"), "jobs/0123");
  EXPECT_EQ(log_field("a b\nc\x01"), "a?b?c?");
  EXPECT_EQ(log_field(std::string(300, 'x'), 10), "xxxxxxxxxx...");
}

}  // namespace
}  // namespace softshock::server
