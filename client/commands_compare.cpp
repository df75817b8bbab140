// softshock diff A B: two runs compared as MLflow's "compare runs" does. The spec fields that
// differ (both specs are the daemon's normalised ones, so a default written out and one left
// implicit compare equal), the summary figures side by side with B's relative difference from A,
// and with --png A-bar(t) of both in one plot.
#include <google/protobuf/struct.pb.h>

#include <cmath>
#include <cstdio>
#include <optional>

#include "client/commands.hpp"
#include "client/format.hpp"

namespace softshock::cli {

namespace {

using google::protobuf::FieldDescriptor;
using google::protobuf::Message;

struct Row {
  std::string name, a, b;
  double a_value = NAN, b_value = NAN;  // numbers, for the relative difference
};

std::string scalar_text(const Message& m, const FieldDescriptor* f, double* number) {
  const auto* r = m.GetReflection();
  *number = NAN;
  switch (f->cpp_type()) {
    case FieldDescriptor::CPPTYPE_DOUBLE:
      *number = r->GetDouble(m, f);
      return fmt_num(*number);
    case FieldDescriptor::CPPTYPE_FLOAT:
      *number = r->GetFloat(m, f);
      return fmt_num(*number);
    case FieldDescriptor::CPPTYPE_INT32:
      *number = r->GetInt32(m, f);
      return std::to_string(r->GetInt32(m, f));
    case FieldDescriptor::CPPTYPE_INT64:
      *number = static_cast<double>(r->GetInt64(m, f));
      return std::to_string(r->GetInt64(m, f));
    case FieldDescriptor::CPPTYPE_UINT32:
      *number = r->GetUInt32(m, f);
      return std::to_string(r->GetUInt32(m, f));
    case FieldDescriptor::CPPTYPE_UINT64:
      *number = static_cast<double>(r->GetUInt64(m, f));
      return std::to_string(r->GetUInt64(m, f));
    case FieldDescriptor::CPPTYPE_BOOL:
      return r->GetBool(m, f) ? "true" : "false";
    case FieldDescriptor::CPPTYPE_STRING:
      return r->GetString(m, f);
    case FieldDescriptor::CPPTYPE_ENUM:
      return r->GetEnum(m, f)->name();
    default:
      return "";
  }
}

std::string repeated_text(const Message& m, const FieldDescriptor* f) {
  const auto* r = m.GetReflection();
  std::string out;
  for (int i = 0; i < r->FieldSize(m, f); ++i) {
    if (!out.empty()) out += "; ";
    if (f->cpp_type() == FieldDescriptor::CPPTYPE_DOUBLE) {
      out += fmt_num(r->GetRepeatedDouble(m, f, i));
    } else if (f->cpp_type() == FieldDescriptor::CPPTYPE_STRING) {
      out += r->GetRepeatedString(m, f, i);
    } else {
      out += '?';
    }
  }
  return out.empty() ? "none" : out;
}

// Every leaf of two messages of one type, by dotted proto path. A message field one side lacks
// (a oneof member of another geometry) reads "-" on that side.
void leaves(const Message* a, const Message* b, const std::string& prefix, std::vector<Row>& out) {
  const auto* type = (a ? a : b)->GetDescriptor();
  for (int i = 0; i < type->field_count(); ++i) {
    const FieldDescriptor* f = type->field(i);
    const std::string path = prefix + f->name();
    auto present = [&](const Message* m) {
      if (m == nullptr) return false;
      if (f->is_repeated()) return true;
      // Messages and oneof members have presence; plain scalars are always there (normalised).
      return (f->cpp_type() != FieldDescriptor::CPPTYPE_MESSAGE && !f->real_containing_oneof()) ||
             m->GetReflection()->HasField(*m, f);
    };
    const bool in_a = present(a), in_b = present(b);
    if (!in_a && !in_b) continue;
    if (f->is_map()) continue;  // no maps in specs or summaries
    if (f->cpp_type() == FieldDescriptor::CPPTYPE_MESSAGE && !f->is_repeated()) {
      leaves(in_a ? &a->GetReflection()->GetMessage(*a, f) : nullptr,
             in_b ? &b->GetReflection()->GetMessage(*b, f) : nullptr, path + ".", out);
      continue;
    }
    Row row{path, "-", "-"};
    if (f->is_repeated()) {
      if (in_a) row.a = repeated_text(*a, f);
      if (in_b) row.b = repeated_text(*b, f);
    } else {
      if (in_a) row.a = scalar_text(*a, f, &row.a_value);
      if (in_b) row.b = scalar_text(*b, f, &row.b_value);
    }
    out.push_back(std::move(row));
  }
}

// B relative to A: "+3.52%", "0", "-" when A is 0 or either is not a number.
std::string relative(const Row& r) {
  if (!std::isfinite(r.a_value) || !std::isfinite(r.b_value)) return "-";
  if (r.a_value == r.b_value) return "0";
  if (r.a_value == 0) return "-";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%+.3g%%", 100.0 * (r.b_value - r.a_value) / std::fabs(r.a_value));
  return buf;
}

std::optional<v1::JobSummary> summary_of(Connection& conn, const std::string& id,
                                         std::string* why) {
  v1::GetJobSummaryRequest request;
  request.set_name(id);
  v1::JobSummary s;
  try {
    conn.unary(
        [&](grpc::ClientContext& ctx) { return conn.service().GetJobSummary(&ctx, request, &s); });
  } catch (const CliError& e) {
    *why = e.what();
    return std::nullopt;
  }
  s.clear_id();  // the ids differ by construction
  return s;
}

void add_rows(google::protobuf::ListValue* list, const std::vector<Row>& rows, bool with_relative) {
  for (const auto& r : rows) {
    auto& f = *list->add_values()->mutable_struct_value()->mutable_fields();
    f["name"].set_string_value(r.name);
    auto value = [](const std::string& text, double number, google::protobuf::Value& v) {
      if (std::isfinite(number)) {
        v.set_number_value(number);
      } else {
        v.set_string_value(text);
      }
    };
    value(r.a, r.a_value, f["a"]);
    value(r.b, r.b_value, f["b"]);
    if (with_relative) {
      if (std::isfinite(r.a_value) && std::isfinite(r.b_value) && r.a_value != 0) {
        f["relative"].set_number_value((r.b_value - r.a_value) / std::fabs(r.a_value));
      } else {
        f["relative"].set_null_value(google::protobuf::NULL_VALUE);
      }
    }
  }
}

}  // namespace

int cmd_diff(const GlobalOptions& g, const ParsedArgs& a) {
  Connection conn(g);
  v1::Job jobs[2];
  for (int k = 0; k < 2; ++k) {
    v1::GetJobRequest request;
    request.set_name(a.positional.at(static_cast<std::size_t>(k)));
    conn.unary(
        [&](grpc::ClientContext& ctx) { return conn.service().GetJob(&ctx, request, &jobs[k]); });
  }
  std::vector<Row> spec_rows, all_spec;
  leaves(&jobs[0].spec(), &jobs[1].spec(), "", all_spec);
  for (auto& r : all_spec) {
    if (r.a != r.b) spec_rows.push_back(std::move(r));
  }
  std::string why_a, why_b;
  auto sa = summary_of(conn, jobs[0].id(), &why_a);
  auto sb = summary_of(conn, jobs[1].id(), &why_b);
  std::vector<Row> summary_rows;
  if (sa || sb) leaves(sa ? &*sa : nullptr, sb ? &*sb : nullptr, "", summary_rows);
  std::erase_if(summary_rows, [](const Row& r) { return r.name == "id"; });  // cleared above

  if (g.json) {
    google::protobuf::Struct out;
    auto& f = *out.mutable_fields();
    f["a"].set_string_value(jobs[0].id());
    f["b"].set_string_value(jobs[1].id());
    add_rows(f["spec"].mutable_list_value(), spec_rows, false);
    add_rows(f["summary"].mutable_list_value(), summary_rows, true);
    std::printf("%s\n", to_json(out).c_str());
  } else {
    std::printf("A: %s  %s  %s\nB: %s  %s  %s\n", jobs[0].id().c_str(),
                state_name(jobs[0].state()).c_str(), join_labels(jobs[0].labels()).c_str(),
                jobs[1].id().c_str(), state_name(jobs[1].state()).c_str(),
                join_labels(jobs[1].labels()).c_str());
    std::printf("\nspec (after defaults): ");
    if (spec_rows.empty()) {
      std::printf("the same%s\n",
                  jobs[0].spec_hash() == jobs[1].spec_hash() && !jobs[0].spec_hash().empty()
                      ? " (equal spec hashes)"
                      : "");
    } else {
      std::printf("%zu fields differ\n", spec_rows.size());
      std::vector<std::vector<std::string>> rows;
      for (const auto& r : spec_rows) rows.push_back({r.name, r.a, r.b, relative(r)});
      print_table(stdout, {"FIELD", "A", "B", "B vs A"}, rows);
    }
    std::printf("\nsummary:");
    if (!sa) std::printf(" A has none (%s);", why_a.c_str());
    if (!sb) std::printf(" B has none (%s);", why_b.c_str());
    std::printf("\n");
    if (!summary_rows.empty()) {
      std::vector<std::vector<std::string>> rows;
      for (const auto& r : summary_rows) rows.push_back({r.name, r.a, r.b, relative(r)});
      print_table(stdout, {"FIGURE", "A", "B", "B vs A"}, rows);
    }
  }
  if (auto png = a.get("png")) {
    write_abar_png(conn, {jobs[0].id(), jobs[1].id()}, 0, *png);
    if (!g.json) std::printf("\nwrote: %s\n", png->c_str());
  }
  return kExitOk;
}

}  // namespace softshock::cli
