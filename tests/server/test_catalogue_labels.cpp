// Labels edited after submission (Catalogue::update_labels, issue 36 item 2): set, overwritten
// and removed in one transaction; an edit past the bound changes nothing; a missing job is
// reported, not created.
#include <gtest/gtest.h>

#include <filesystem>
#include <random>

#include "server/store/catalogue.hpp"

namespace softshock::server {
namespace {

namespace fs = std::filesystem;

class CatalogueLabelsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ =
        fs::temp_directory_path() / ("softshock-labels-" + std::to_string(std::random_device{}()));
    fs::create_directories(dir_);
    catalogue_ = std::make_unique<Catalogue>((dir_ / "catalogue.sqlite").string());
    NewJob j;
    j.id = "j1";
    j.spec_json = R"({"run":{"end_time":5e-09}})";
    j.spec_hash = "hash-j1";
    j.create_us = now_us();
    j.owner = "alice";
    j.labels = {{"study", "a"}, {"case", "1"}};
    ASSERT_TRUE(catalogue_->insert(j).created);
  }
  void TearDown() override {
    catalogue_.reset();
    fs::remove_all(dir_);
  }

  fs::path dir_;
  std::unique_ptr<Catalogue> catalogue_;
};

TEST_F(CatalogueLabelsTest, SetsOverwritesAndRemoves) {
  const auto u = catalogue_->update_labels("j1", {{"study", "b"}, {"note", "x"}}, {"case"}, 64);
  ASSERT_TRUE(u.job);
  EXPECT_EQ(u.too_many, 0u);
  const std::map<std::string, std::string> expected{{"study", "b"}, {"note", "x"}};
  EXPECT_EQ(u.job->labels, expected);
  EXPECT_EQ(catalogue_->get("j1")->labels, expected) << "stored, not only answered";
  // Removing a key the job lacks is no error.
  EXPECT_TRUE(catalogue_->update_labels("j1", {}, {"absent"}, 64).job);
}

TEST_F(CatalogueLabelsTest, PastTheBoundNothingChanges) {
  const auto u = catalogue_->update_labels("j1", {{"x", "1"}, {"y", "2"}}, {"case"}, 2);
  EXPECT_FALSE(u.job);
  EXPECT_EQ(u.too_many, 3u);  // study, x, y
  const std::map<std::string, std::string> before{{"study", "a"}, {"case", "1"}};
  EXPECT_EQ(catalogue_->get("j1")->labels, before) << "rolled back, the removal too";
  // Replacing within the bound is fine.
  EXPECT_TRUE(catalogue_->update_labels("j1", {{"x", "1"}}, {"case"}, 2).job);
}

TEST_F(CatalogueLabelsTest, MissingJob) {
  const auto u = catalogue_->update_labels("nope", {{"k", "v"}}, {}, 64);
  EXPECT_FALSE(u.job);
  EXPECT_EQ(u.too_many, 0u);
  EXPECT_FALSE(catalogue_->get("nope"));
}

}  // namespace
}  // namespace softshock::server
