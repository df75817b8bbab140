// What the files of SimulationService (simulation_service*.cpp) share: status helpers,
// timestamps, page tokens and sizes, the summary message, submission checks and the slot of
// the bounded stream pool.
#pragma once

#include <google/protobuf/timestamp.pb.h>
#include <grpcpp/grpcpp.h>

#include <cstdint>
#include <string>

#include "server/transport/simulation_service.hpp"
#include "softshock/v1/service.pb.h"
#include "solver/run_spec.hpp"
#include "solver/run_summary.hpp"

namespace softshock::server {

namespace rpc {

inline constexpr int kDefaultPageSize = 50;
inline constexpr int kMaxPageSize = 1000;
// A page stops growing past this many bytes of items (the first item always goes in): well
// under gRPC's default 4 MiB receive limit, whatever the items carry.
inline constexpr std::size_t kMaxPageBytes = 1 << 20;

class PageBudget {
 public:
  // True if an item of `bytes` goes in this page (and counts it); false once the page is full.
  bool take(std::size_t bytes) {
    if (used_ > 0 && used_ + bytes > kMaxPageBytes) return false;
    used_ += bytes;
    return true;
  }

 private:
  std::size_t used_ = 0;
};

// An `owner` list filter: empty (anyone) or a user name (policy/users.hpp).
grpc::Status check_owner_filter(const std::string& owner);

grpc::Status invalid(const std::string& field, const std::string& rule);
grpc::Status not_found(const std::string& id);

// A Timestamp inside 0001-01-01..9999-12-31 with nanos in 0..999,999,999 (google.protobuf's
// own rule): only those convert to microseconds without overflowing int64.
bool valid_timestamp(const google::protobuf::Timestamp& t);
int64_t timestamp_us(const google::protobuf::Timestamp& t);
void set_timestamp(int64_t us, google::protobuf::Timestamp* t);

// Page tokens are base64url("CURSOR:FINGERPRINT"): the cursor is the handler's own position
// text, the fingerprint binds the token to the request's other fields (AIP-158: they must
// match across pages). An empty token gives an empty cursor (the first page).
std::string make_page_token(const std::string& cursor, const std::string& fingerprint);
grpc::Status read_page_token(const std::string& page_token, const std::string& fingerprint,
                             std::string* cursor);
bool parse_seq_cursor(const std::string& cursor, int64_t* seq);
// page_size 0 = the default, capped at kMaxPageSize; negative = INVALID_ARGUMENT.
grpc::Status page_size_of(int32_t requested, int* page_size);

// NaN stays NaN: the protobuf double carries it, and clients read it as "not known".
void fill_groups(const NondimensionalGroups& from, v1::NondimensionalGroups* g);
void fill_summary(const std::string& id, const RunSummary& s, v1::JobSummary* resp);

// request_id and labels of SubmitJob and SubmitGrid.
grpc::Status check_request_id_and_labels(
    const std::string& request_id, const google::protobuf::Map<std::string, std::string>& labels);
// The label rules (at most kMaxLabels; keys 1..63 characters without '='; values at most 255),
// errors naming `field` ("labels", UpdateJobLabels' "set").
inline constexpr std::size_t kMaxLabels = 64;
grpc::Status check_labels(const std::string& field,
                          const google::protobuf::Map<std::string, std::string>& labels);
// INVALID_ARGUMENT for a SpecError found under `prefix` ("spec", "base_spec", or "" for grid
// fields), with the field path repeated in the trailing metadata.
grpc::Status spec_invalid(grpc::ServerContext* ctx, const std::string& prefix, const SpecError& e);

}  // namespace rpc

// RAII slot of the bounded pool of concurrent streams.
class StreamSlot {
 public:
  explicit StreamSlot(SimulationService& s) : s_(s) {
    acquired_ = s_.active_streams_.fetch_add(1) < s_.config_.max_streams;
  }
  ~StreamSlot() { s_.active_streams_.fetch_sub(1); }
  bool acquired() const { return acquired_; }

 private:
  SimulationService& s_;
  bool acquired_;
};

}  // namespace softshock::server
