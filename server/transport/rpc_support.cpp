#include "server/transport/rpc_support.hpp"

#include <google/protobuf/util/time_util.h>

#include <algorithm>
#include <cstring>

#include "server/policy/users.hpp"
#include "server/transport/rpc_guard.hpp"

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

void fill_groups(const NondimensionalGroups& from, v1::NondimensionalGroups* g) {
  g->set_pbar(from.pbar);
  g->set_tbar_pulse(from.tbar_pulse);
  g->set_mubar(from.mubar);
  g->set_gamma(from.gamma);
  g->set_c1(from.c1);
  g->set_c2(from.c2);
  g->set_time_scale_s(from.time_scale_s);
}

void fill_summary(const std::string& id, const RunSummary& s, v1::JobSummary* resp) {
  resp->set_id(id);
  resp->set_elements(static_cast<int64_t>(s.elements));
  resp->set_nodes(static_cast<int64_t>(s.nodes));
  resp->set_steps(s.steps);
  resp->set_wall_time_s(s.wall_time_s);
  resp->set_end_time_s(s.end_time_s);
  fill_groups(s.groups, resp->mutable_groups());
  resp->set_energy_injected_j_per_m(s.energy_injected_J_per_m);
  resp->set_energy_after_pulse_j_per_m(s.energy_after_pulse_J_per_m);
  resp->set_max_abar_first_cycle(s.max_abar_first_cycle);
  resp->set_max_abar(s.max_abar);
  resp->set_dominant_mode_end(s.dominant_mode_end);
  resp->set_shock_at_center_s(s.shock_at_center_s);
  for (double t : s.rim_reflections_s) resp->add_rim_reflections_s(t);
  resp->set_min_dt_s(s.min_dt_s);
  resp->set_max_dt_s(s.max_dt_s);
  resp->set_kernel_time_s(s.kernel_time_s);
  resp->set_grind_ns(s.grind_ns());
  resp->set_kernel_grind_ns(s.kernel_grind_ns());
  resp->set_meshing_time_s(s.meshing_time_s);
  resp->set_meshing_share(s.meshing_share());
  resp->set_mesh_cache(s.mesh_cache);
  resp->set_abar_end(s.abar_end);
  resp->set_max_abar_filtered_first_cycle(s.max_abar_filtered_first_cycle);
  resp->set_max_abar_filtered(s.max_abar_filtered);
  resp->set_abar_filtered_end(s.abar_filtered_end);
  resp->set_max_aspect_ratio(s.max_aspect_ratio);
  resp->set_aspect_ratio_above_10_s(s.aspect_ratio_above_10_s);
  resp->set_solver_revision(s.solver_revision);
  resp->set_diagnostics_time_s(s.diagnostics_time_s);
  resp->set_diagnostics_share(s.diagnostics_share());
  resp->set_output_time_s(s.output_time_s);
  resp->set_output_share(s.output_share());
  resp->set_dimension(s.dimension);
  resp->set_thickness_m(s.thickness_m);
  if (s.damage) {
    resp->set_damage(true);
    resp->set_damage_onset_s(s.damage_onset_s);
    resp->set_max_damaged_volume(s.max_damaged_volume);
    resp->set_max_damaged_radius_m(s.max_damaged_radius_m);
    resp->set_damage_dissipation_j_per_m(s.damage_dissipation_J_per_m);
    resp->set_crack_energy_j_per_m(s.crack_energy_J_per_m);
    resp->set_damage_time_s(s.damage_time_s);
    resp->set_damage_solves(s.damage_solves);
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
