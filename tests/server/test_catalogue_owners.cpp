// The catalogue's owners and room (issue 35): a schema-7 data folder upgrades with every job and
// grid owned by the default user; owners are stored, listed and queried; the per-owner bound on
// queued jobs is counted inside the insert; and on a full disk (a real tmpfs of a few MiB,
// mounted in a private mount namespace) an insert fails as CatalogueFull while a deletion still
// commits through the catalogue's reserved room -- which it cannot without one.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sched.h>
#include <sys/mount.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <random>

#include "server/store/catalogue.hpp"
#include "server/store/catalogue_schema.hpp"
#include "server/store/sqlite_connection.hpp"

namespace softshock::server {
namespace {

namespace fs = std::filesystem;

NewJob job(const std::string& id, const std::string& owner) {
  NewJob j;
  j.id = id;
  j.spec_json = R"({"run":{"end_time":5e-09}})";
  j.spec_hash = "hash-" + id;
  j.create_us = now_us();
  j.owner = owner;
  j.labels = {{"study", "owners"}};
  return j;
}

// prefix + i (appended: GCC 12's -Wrestrict misfires on `"j" + std::to_string(i)` here).
std::string numbered(const std::string& prefix, int i) {
  std::string out = prefix;
  out += std::to_string(i);
  return out;
}

class CatalogueOwnersTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ =
        fs::temp_directory_path() / ("softshock-owners-" + std::to_string(std::random_device{}()));
    fs::create_directories(dir_);
    path_ = (dir_ / "catalogue.sqlite").string();
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path dir_;
  std::string path_;
};

TEST_F(CatalogueOwnersTest, SchemaSevenUpgradesWithEveryJobOwnedByTheDefaultUser) {
  {
    // A catalogue exactly as a softshockd of schema 7 left it: its migrations, its rows.
    detail::SqliteConnection old(path_);
    old.exec("CREATE TABLE schema_version (version INTEGER NOT NULL)");
    old.exec("INSERT INTO schema_version(version) VALUES (7)");
    for (int v = 0; v < 7; ++v) old.exec(detail::catalogue_migration(v));
    old.exec(
        "INSERT INTO jobs(id, state, spec_json, spec_hash, create_time_us) "
        "VALUES ('old-queued', 1, '{}', 'h1', 1), ('old-done', 3, '{}', 'h2', 2)");
    old.exec(
        "INSERT INTO grids(id, create_time_us, point_count, definition) "
        "VALUES ('old-grid', 3, 0, '{}')");
  }
  Catalogue c(path_);
  EXPECT_EQ(c.schema_version(), 10);
  for (const char* id : {"old-queued", "old-done"}) {
    auto j = c.get(id);
    ASSERT_TRUE(j) << id;
    EXPECT_EQ(j->owner, "default") << id;
  }
  ASSERT_TRUE(c.get_grid("old-grid"));
  EXPECT_EQ(c.get_grid("old-grid")->owner, "default");
  ListFilter mine;
  mine.owner = "default";
  EXPECT_EQ(c.list(mine).size(), 2u);
  mine.owner = "alice";
  EXPECT_TRUE(c.list(mine).empty());
  EXPECT_EQ(c.queued_of("default"), 1);
}

TEST_F(CatalogueOwnersTest, OwnersAreStoredListedAndQueried) {
  Catalogue c(path_);
  c.insert(job("a1", "alice"));
  c.insert(job("b1", "bob"));
  c.insert(job("a2", "alice"));
  EXPECT_EQ(c.get("b1")->owner, "bob");
  ListFilter f;
  f.owner = "alice";
  const auto alice = c.list(f);
  ASSERT_EQ(alice.size(), 2u);
  EXPECT_EQ(alice[0].id, "a2");  // newest first, as ever
  EXPECT_EQ(alice[1].id, "a1");
  f.owner.clear();
  EXPECT_EQ(c.list(f).size(), 3u);
  JobQuery q;
  q.owner = "bob";
  const auto bob = c.query(q);
  ASSERT_EQ(bob.size(), 1u);
  EXPECT_EQ(bob[0].job.owner, "bob");

  NewGrid g;
  g.id = "g";
  g.definition = "{}";
  g.owner = "carol";
  g.create_us = now_us();
  c.insert_grid(g, {job("g0", "carol")});
  EXPECT_EQ(c.get_grid("g")->owner, "carol");
  EXPECT_EQ(c.list_grids(0, 10, "carol").size(), 1u);
  EXPECT_TRUE(c.list_grids(0, 10, "alice").empty());
  EXPECT_EQ(c.list_grids(0, 10).size(), 1u);
}

TEST_F(CatalogueOwnersTest, PerOwnerQueueBoundIsCountedInTheInsert) {
  Catalogue c(path_);
  EXPECT_TRUE(c.insert(job("a1", "alice"), 2).created);
  EXPECT_TRUE(c.insert(job("a2", "alice"), 2).created);
  const auto refused = c.insert(job("a3", "alice"), 2);
  EXPECT_TRUE(refused.refused);
  EXPECT_FALSE(refused.created);
  EXPECT_EQ(refused.owner_queued, 2);
  EXPECT_FALSE(c.get("a3")) << "a refused job leaves no row";
  EXPECT_TRUE(c.insert(job("b1", "bob"), 2).created) << "the bound is per owner";
  ASSERT_TRUE(c.start("a1", now_us()));  // running jobs no longer wait
  EXPECT_TRUE(c.insert(job("a3", "alice"), 2).created);
  EXPECT_EQ(c.queued_of("alice"), 2);

  // A grid's points that must run count all together; reused ones do not count.
  NewGrid g;
  g.id = "g";
  g.definition = "{}";
  g.owner = "bob";
  g.create_us = now_us();
  std::vector<NewJob> points = {job("p0", "bob"), job("p1", "bob")};
  const auto grid = c.insert_grid(g, points, 2);
  EXPECT_TRUE(grid.refused);
  EXPECT_EQ(grid.owner_queued, 1);
  EXPECT_FALSE(c.get_grid("g"));
  EXPECT_FALSE(c.get("p0"));
  points.pop_back();
  EXPECT_TRUE(c.insert_grid(g, points, 2).created);
}

// Runs `scenario` in a child process with its own mount namespace, where `dir` is a tmpfs of
// `bytes`. Returns the child's exit status; 77 = no tmpfs could be mounted (no privileges).
int on_tiny_disk(const fs::path& dir, std::size_t bytes, const std::function<int()>& scenario) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    const uid_t uid = ::geteuid();
    const gid_t gid = ::getegid();
    int flags = CLONE_NEWNS;
    if (uid != 0) flags |= CLONE_NEWUSER;  // unprivileged: become root of a user namespace
    if (::unshare(flags) != 0) ::_exit(77);
    if (uid != 0) {
      std::ofstream("/proc/self/setgroups") << "deny";
      std::ofstream("/proc/self/uid_map") << "0 " << uid << " 1";
      std::ofstream("/proc/self/gid_map") << "0 " << gid << " 1";
    }
    if (::mount(nullptr, "/", nullptr, MS_REC | MS_PRIVATE, nullptr) != 0) ::_exit(77);
    const std::string size = "size=" + std::to_string(bytes);
    if (::mount("tmpfs", dir.c_str(), "tmpfs", 0, size.c_str()) != 0) ::_exit(77);
    int code = 1;
    try {
      code = scenario();
    } catch (const std::exception& e) {
      std::cerr << "scenario threw: " << e.what() << "\n";
      code = 2;
    }
    ::_exit(code);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

// Writes a file until the disk refuses another byte.
void fill(const fs::path& file) {
  const int fd = ::open(file.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0600);
  static const char block[4096] = {};
  while (::write(fd, block, sizeof block) > 0) {
  }
  while (::write(fd, block, 1) > 0) {
  }
  ::close(fd);
}

// Inserts jobs until the catalogue cannot grow: whatever slack its write-ahead log had is used.
bool insert_until_full(Catalogue& c, const std::string& prefix) {
  for (int i = 0; i < 100000; ++i) {
    try {
      c.insert(job(numbered(prefix, i), "alice"));
    } catch (const CatalogueFull&) {
      return true;
    }
  }
  return false;
}

#define SCENARIO_CHECK(cond, code)                                    \
  do {                                                                \
    if (!(cond)) {                                                    \
      std::cerr << "scenario: " #cond " failed at line " << __LINE__; \
      return code;                                                    \
    }                                                                 \
  } while (0)

// How many of the jobs `ids` can be erased, in order, before the first CatalogueFull.
int erase_until_full(Catalogue& c, int first, int count) {
  for (int i = first; i < first + count; ++i) {
    try {
      if (!c.erase(numbered("j", i))) return -1;
    } catch (const CatalogueFull&) {
      return i - first;
    }
  }
  return count;
}

TEST_F(CatalogueOwnersTest, OnAFullDiskInsertsFailAsFullAndDeletionsUseTheRoom) {
  const fs::path disk = dir_ / "disk";
  fs::create_directories(disk);
  const std::string db = (disk / "catalogue.sqlite").string();
  const int status = on_tiny_disk(disk, 8 << 20, [&]() -> int {
    // Without a room, as before: once full, deletions fail too. A failed commit leaves some of
    // the write-ahead log's space behind, which may hold one small commit, hardly two.
    {
      Catalogue c(db, 0);
      for (int i = 0; i < 20; ++i) c.insert(job(numbered("j", i), "alice"));
      fill(disk / "filler");
      SCENARIO_CHECK(insert_until_full(c, "x"), 3);
      const int erased = erase_until_full(c, 0, 10);
      std::cerr << "without a room: " << erased << " of 10 deletions committed\n";
      SCENARIO_CHECK(erased >= 0 && erased < 10, 4);  // the failure the room exists for
    }
    fs::remove(disk / "filler");
    // With a room: inserts still fail on a full disk and leave the room alone; the same ten
    // deletions, and a cancellation, commit.
    Catalogue c(db, 2 << 20);
    SCENARIO_CHECK(c.room_held(), 5);
    fill(disk / "filler");
    SCENARIO_CHECK(insert_until_full(c, "y"), 6);
    SCENARIO_CHECK(c.room_held(), 7);
    const int erased = erase_until_full(c, 10, 10);
    std::cerr << "with a room: " << erased << " of 10 deletions committed\n";
    SCENARIO_CHECK(erased == 10, 8);
    SCENARIO_CHECK(!c.room_held(), 9);
    SCENARIO_CHECK(!c.get("j19"), 10);
    SCENARIO_CHECK(c.cancel_queued("j0", now_us()), 11);
    SCENARIO_CHECK(c.get("j0")->state == JobState::kCancelled, 12);
    SCENARIO_CHECK(!c.refill_room(), 13);  // no space for it yet
    fs::remove(disk / "filler");
    SCENARIO_CHECK(c.refill_room() && c.room_held(), 14);
    SCENARIO_CHECK(c.insert(job("after", "alice")).created, 15);
    return 0;
  });
  if (status == 77) GTEST_SKIP() << "cannot mount a tmpfs here (no privileges)";
  EXPECT_EQ(status, 0) << "the scenario failed with status " << status << " (see stderr)";
}

}  // namespace
}  // namespace softshock::server
