// FileDigests (DownloadResult's SHA-256 of result files): the digest of the whole file, computed
// once per file identity; a changed file is hashed anew; a cancelled hash gives nothing.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <random>

#include "server/store/file_digests.hpp"

namespace softshock::server {
namespace {

namespace fs = std::filesystem;

class FileDigestsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    path_ = fs::temp_directory_path() /
            ("softshock-digest-" + std::to_string(std::random_device{}()) + ".bin");
  }
  void TearDown() override { fs::remove(path_); }
  void write(const std::string& text) {
    std::ofstream(path_, std::ios::binary | std::ios::trunc) << text;
  }
  int open_file() { return ::open(path_.c_str(), O_RDONLY | O_CLOEXEC); }

  fs::path path_;
};

TEST_F(FileDigestsTest, DigestOnceThenFromMemory) {
  write("abc");
  FileDigests digests;
  const int fd = open_file();
  ASSERT_GE(fd, 0);
  // FIPS 180-2's example: SHA-256("abc").
  const std::string abc = "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad";
  EXPECT_EQ(digests.digest(fd, {}), abc);
  EXPECT_EQ(digests.digest(fd, {}), abc);
  EXPECT_EQ(digests.computed(), 1u);
  ::close(fd);

  write("abcd");  // another size: hashed again
  const int fd2 = open_file();
  EXPECT_EQ(digests.digest(fd2, {}),
            "88d4266fd4e6338d13b845fcf289579d209c897823b9217da3e161936f031589");
  EXPECT_EQ(digests.computed(), 2u);
  ::close(fd2);
}

TEST_F(FileDigestsTest, LargerThanOneBlockAndCancelled) {
  write(std::string((3u << 20) + 17, 'x'));
  FileDigests digests;
  const int fd = open_file();
  EXPECT_FALSE(digests.digest(fd, [] { return true; }));
  EXPECT_EQ(digests.computed(), 0u);
  const auto whole = digests.digest(fd, {});
  ASSERT_TRUE(whole);
  EXPECT_EQ(whole->size(), 64u);
  ::close(fd);
}

}  // namespace
}  // namespace softshock::server
