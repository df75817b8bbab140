// Requests name a job or grid by `name` (AIP-131) or by the `id` alias: what each accepts, and
// errors that name the field and the rule.
#include <gtest/gtest.h>

#include "server/transport/resource_name.hpp"

namespace softshock::server {
namespace {

std::string id_of(const std::string& name, const std::string& alias,
                  const std::string& collection = "jobs/") {
  std::string id = "unset";
  const grpc::Status st = requested_id(name, alias, collection, &id);
  return st.ok() ? id : "error: " + st.error_message();
}

TEST(ResourceName, NameOrIdAliasGiveTheId) {
  EXPECT_EQ(id_of("jobs/abc-1", ""), "abc-1");
  EXPECT_EQ(id_of("abc-1", ""), "abc-1");
  EXPECT_EQ(id_of("", "jobs/abc-1"), "abc-1");
  EXPECT_EQ(id_of("", "abc_1"), "abc_1");
  EXPECT_EQ(id_of("jobs/abc", "abc"), "abc");  // both, agreeing
  EXPECT_EQ(id_of("grids/g7", "", "grids/"), "g7");
}

TEST(ResourceName, ErrorsNameTheFieldAndTheRule) {
  std::string id;
  const grpc::Status none = requested_id("", "", "jobs/", &id);
  EXPECT_EQ(none.error_code(), grpc::StatusCode::INVALID_ARGUMENT);
  EXPECT_EQ(none.error_message().rfind("name: required", 0), 0u) << none.error_message();
  EXPECT_EQ(id_of("grids/g7", ""),
            "error: name: 'grids/g7' must be jobs/{id} or the bare id, "
            "id = [A-Za-z0-9_-]{1,64}");
  EXPECT_EQ(id_of("", "a/b").rfind("error: id: 'a/b' must be", 0), 0u);
  EXPECT_EQ(id_of("jobs/a", "b"), "error: name: 'jobs/a' and id: 'b' name different jobs");
  EXPECT_EQ(id_of("", std::string(65, 'x')).rfind("error: id:", 0), 0u);
}

}  // namespace
}  // namespace softshock::server
