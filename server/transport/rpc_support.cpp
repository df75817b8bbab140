#include "server/transport/rpc_support.hpp"

#include <google/protobuf/util/time_util.h>

#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <vector>

#include "server/policy/users.hpp"
#include "server/transport/rpc_guard.hpp"
#include "solver/summary_figures.hpp"

namespace softshock::server::rpc {

using google::protobuf::util::TimeUtil;
using grpc::Status;
using grpc::StatusCode;

namespace {

constexpr std::size_t kMaxLabelKey = 63;
constexpr std::size_t kMaxLabelValue = 255;
constexpr std::size_t kMaxRequestId = 128;

const char kBase64[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789-_";

std::string base64url_encode(const std::string& in) {
  std::string out;
  uint32_t buffer = 0;
  int bits = 0;
  for (unsigned char c : in) {
    buffer = (buffer << 8) | c;
    bits += 8;
    while (bits >= 6) {
      bits -= 6;
      out += kBase64[(buffer >> bits) & 63];
    }
  }
  if (bits > 0) out += kBase64[(buffer << (6 - bits)) & 63];
  return out;
}

bool base64url_decode(const std::string& in, std::string* out) {
  out->clear();
  uint32_t buffer = 0;
  int bits = 0;
  for (char c : in) {
    const char* p = std::strchr(kBase64, c);
    if (c == '\0' || p == nullptr) return false;
    buffer = (buffer << 6) | static_cast<uint32_t>(p - kBase64);
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      *out += static_cast<char>((buffer >> bits) & 0xff);
    }
  }
  return true;
}

}  // namespace

Status check_owner_filter(const std::string& owner) {
  if (owner.empty() || valid_user_name(owner)) return Status::OK;
  return invalid("owner", "must be a user name: 1 to 64 of A-Z a-z 0-9 . _ -");
}

Status invalid(const std::string& field, const std::string& rule) {
  return {StatusCode::INVALID_ARGUMENT, field + ": " + rule};
}
Status not_found(const std::string& id) {
  return {StatusCode::NOT_FOUND, "job " + id + " not found"};
}

bool valid_timestamp(const google::protobuf::Timestamp& t) {
  return t.seconds() >= TimeUtil::kTimestampMinSeconds &&
         t.seconds() <= TimeUtil::kTimestampMaxSeconds && t.nanos() >= 0 &&
         t.nanos() <= 999'999'999;
}

int64_t timestamp_us(const google::protobuf::Timestamp& t) {
  return TimeUtil::TimestampToMicroseconds(t);
}
void set_timestamp(int64_t us, google::protobuf::Timestamp* t) {
  *t = TimeUtil::MicrosecondsToTimestamp(us);
}

std::string make_page_token(const std::string& cursor, const std::string& fingerprint) {
  return base64url_encode(cursor + ":" + fingerprint);
}

Status read_page_token(const std::string& page_token, const std::string& fingerprint,
                       std::string* cursor) {
  cursor->clear();
  if (page_token.empty()) return Status::OK;
  std::string token;
  const auto colon = [&] { return token.rfind(':'); };
  if (!base64url_decode(page_token, &token) || colon() == std::string::npos || colon() == 0) {
    return invalid("page_token", "not a token this server issued");
  }
  if (token.substr(colon() + 1) != fingerprint) {
    return invalid("page_token", "the filters differ from those of the first page");
  }
  *cursor = token.substr(0, colon());
  return Status::OK;
}

bool parse_seq_cursor(const std::string& cursor, int64_t* seq) {
  try {
    std::size_t used = 0;
    *seq = std::stoll(cursor, &used);
    return used == cursor.size() && *seq > 0;
  } catch (const std::exception&) {
    return false;
  }
}

Status page_size_of(int32_t requested, int* page_size) {
  if (requested < 0) return invalid("page_size", "must not be negative");
  *page_size = requested == 0 ? kDefaultPageSize : std::min<int>(requested, kMaxPageSize);
  return Status::OK;
}

namespace {

// A summary figure and the field of the same name in JobSummary (or, for kInGroups figures, in
// NondimensionalGroups): transport fills the message from summary_figures(), by name.
struct FigureField {
  const SummaryFigure* figure;
  const google::protobuf::FieldDescriptor* field;
};

std::vector<FigureField> figure_fields(bool groups) {
  const auto* message =
      groups ? v1::NondimensionalGroups::descriptor() : v1::JobSummary::descriptor();
  std::vector<FigureField> out;
  for (const auto& f : summary_figures()) {
    if (f.has(kNotInJobSummary) || f.has(kInGroups) != groups) continue;
    const auto* field = message->FindFieldByName(f.name);
    // tests/server/test_summary_figures.cpp holds the table and the message to each other.
    if (!field) throw std::logic_error(std::string("JobSummary has no field ") + f.name);
    out.push_back({&f, field});
  }
  return out;
}

void set_field(google::protobuf::Message* m, const FigureField& ff, const RunSummary& s) {
  using google::protobuf::FieldDescriptor;
  const auto* r = m->GetReflection();
  const SummaryFigure& f = *ff.figure;
  if (ff.field->is_repeated()) {
    for (double v : f.series(s)) r->AddDouble(m, ff.field, v);
    return;
  }
  switch (ff.field->cpp_type()) {
    case FieldDescriptor::CPPTYPE_DOUBLE:
      r->SetDouble(m, ff.field, f.get(s));
      break;
    case FieldDescriptor::CPPTYPE_INT64:
      r->SetInt64(m, ff.field, static_cast<int64_t>(f.get(s)));
      break;
    case FieldDescriptor::CPPTYPE_INT32:
      r->SetInt32(m, ff.field, static_cast<int32_t>(f.get(s)));
      break;
    case FieldDescriptor::CPPTYPE_BOOL:
      r->SetBool(m, ff.field, f.get(s) != 0);
      break;
    case FieldDescriptor::CPPTYPE_STRING:
      r->SetString(m, ff.field, f.text(s));
      break;
    default:
      throw std::logic_error(std::string("JobSummary.") + f.name + ": unexpected type");
  }
}

}  // namespace

void fill_groups(const NondimensionalGroups& from, v1::NondimensionalGroups* g) {
  static const std::vector<FigureField> fields = figure_fields(true);
  RunSummary s;
  s.groups = from;
  for (const auto& ff : fields) set_field(g, ff, s);
}

// Every figure a JobSummary carries; the damage figures only for a run with damage.
void fill_summary(const std::string& id, const RunSummary& s, v1::JobSummary* resp) {
  static const std::vector<FigureField> fields = figure_fields(false);
  resp->set_id(id);
  fill_groups(s.groups, resp->mutable_groups());
  for (const auto& ff : fields) {
    if (ff.figure->has(kOnlyDamage) && !s.damage) continue;
    set_field(resp, ff, s);
  }
}

Status check_request_id_and_labels(const std::string& request_id,
                                   const google::protobuf::Map<std::string, std::string>& labels) {
  if (request_id.size() > kMaxRequestId) {
    return invalid("request_id", "at most " + std::to_string(kMaxRequestId) + " characters");
  }
  return check_labels("labels", labels);
}

Status check_labels(const std::string& field,
                    const google::protobuf::Map<std::string, std::string>& labels) {
  if (labels.size() > kMaxLabels) {
    return invalid(field, "at most " + std::to_string(kMaxLabels) + " labels");
  }
  for (const auto& [key, value] : labels) {
    if (key.empty() || key.size() > kMaxLabelKey || key.find('=') != std::string::npos) {
      return invalid(field,
                     "keys must be 1.." + std::to_string(kMaxLabelKey) + " characters without '='");
    }
    if (value.size() > kMaxLabelValue) {
      return invalid(field + "[" + key + "]",
                     "values must be at most " + std::to_string(kMaxLabelValue) + " characters");
    }
  }
  return Status::OK;
}

Status spec_invalid(grpc::ServerContext* ctx, const std::string& prefix, const SpecError& e) {
  const std::string dot = prefix.empty() ? "" : prefix + ".";
  ctx->AddTrailingMetadata("softshock-field", dot + e.field());
  return {StatusCode::INVALID_ARGUMENT, dot + e.what()};
}

}  // namespace softshock::server::rpc
