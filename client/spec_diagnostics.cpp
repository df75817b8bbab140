#include "client/spec_diagnostics.hpp"

#include <google/protobuf/struct.pb.h>
#include <google/protobuf/util/json_util.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <limits>

#include "client/cli_common.hpp"

namespace softshock::cli {

namespace {

using google::protobuf::Descriptor;
using google::protobuf::FieldDescriptor;
using google::protobuf::Value;

std::string lower(const std::string& s) {
  std::string out = s;
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

std::string join(const std::vector<std::string>& items, const char* separator = ", ") {
  std::string out;
  for (const auto& s : items) out += (out.empty() ? "" : separator) + s;
  return out;
}

// A field of `type` by its proto name or its JSON name (protobuf's parser takes both).
const FieldDescriptor* find_field(const Descriptor* type, const std::string& name) {
  for (int i = 0; i < type->field_count(); ++i) {
    const FieldDescriptor* f = type->field(i);
    if (f->name() == name || f->json_name() == name) return f;
  }
  return nullptr;
}

std::vector<std::string> field_names(const Descriptor* type) {
  std::vector<std::string> names;
  for (int i = 0; i < type->field_count(); ++i) names.push_back(type->field(i)->name());
  return names;
}

// "geometry.disk.radus: no such field in Disk; did you mean radius? (fields: radius)".
std::string unknown_field(const std::string& path, const std::string& key, const Descriptor* type) {
  // Suggest among both spellings, answer with the proto one (what the docs show).
  std::vector<std::string> candidates;
  for (int i = 0; i < type->field_count(); ++i) {
    candidates.push_back(type->field(i)->name());
    candidates.push_back(type->field(i)->json_name());
  }
  std::string hint;
  if (auto chosen = closest(key, candidates))
    hint = "; did you mean " + find_field(type, *chosen)->name() + "?";
  return path + key + ": no such field in " + type->name() + hint +
         " (fields: " + join(field_names(type)) + ")";
}

std::string describe(const Value& v) {
  switch (v.kind_case()) {
    case Value::kNullValue:
      return "null";
    case Value::kNumberValue: {
      char buf[64];
      std::snprintf(buf, sizeof buf, "%.17g", v.number_value());
      return std::string("a number (") + buf + ")";
    }
    case Value::kStringValue:
      return "text (\"" + v.string_value().substr(0, 40) + "\")";
    case Value::kBoolValue:
      return v.bool_value() ? "true" : "false";
    case Value::kStructValue:
      return "an object";
    case Value::kListValue:
      return "a list";
    default:
      return "nothing";
  }
}

// What a field wants, in words.
std::string wants(const FieldDescriptor* f) {
  switch (f->type()) {
    case FieldDescriptor::TYPE_DOUBLE:
    case FieldDescriptor::TYPE_FLOAT:
      return "a number";
    case FieldDescriptor::TYPE_INT32:
    case FieldDescriptor::TYPE_INT64:
    case FieldDescriptor::TYPE_SINT32:
    case FieldDescriptor::TYPE_SINT64:
    case FieldDescriptor::TYPE_SFIXED32:
    case FieldDescriptor::TYPE_SFIXED64:
      return "a whole number";
    case FieldDescriptor::TYPE_UINT32:
    case FieldDescriptor::TYPE_UINT64:
    case FieldDescriptor::TYPE_FIXED32:
    case FieldDescriptor::TYPE_FIXED64:
      return "a whole number >= 0";
    case FieldDescriptor::TYPE_BOOL:
      return "true or false";
    case FieldDescriptor::TYPE_STRING:
      return "text";
    case FieldDescriptor::TYPE_BYTES:
      return "base64 text";
    case FieldDescriptor::TYPE_ENUM:
      return "one of the names of " + f->enum_type()->name();
    default:
      return "an object (" + f->message_type()->name() + ")";
  }
}

std::vector<std::string> enum_names(const google::protobuf::EnumDescriptor* e) {
  std::vector<std::string> names;
  for (int i = 0; i < e->value_count(); ++i) {
    const std::string& n = e->value(i)->name();
    if (n.size() < 12 || n.compare(n.size() - 12, 12, "_UNSPECIFIED") != 0) names.push_back(n);
  }
  return names;
}

bool number_text(const std::string& s, double* out) {
  if (s == "NaN" || s == "Infinity" || s == "-Infinity") {
    *out = s == "NaN" ? NAN : (s[0] == '-' ? -INFINITY : INFINITY);
    return true;
  }
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), *out);
  return ec == std::errc() && end == s.data() + s.size();
}

std::optional<std::string> check_message(const Value& v, const Descriptor* type,
                                         const std::string& path);

std::optional<std::string> check_single(const FieldDescriptor* f, const Value& v,
                                        const std::string& where) {
  if (v.kind_case() == Value::kNullValue) return std::nullopt;  // null = the default
  const auto wrong = [&] { return where + ": expects " + wants(f) + ", got " + describe(v); };
  double number = 0;
  const bool is_number =
      v.kind_case() == Value::kNumberValue
          ? (number = v.number_value(), true)
          : v.kind_case() == Value::kStringValue && number_text(v.string_value(), &number);
  switch (f->cpp_type()) {
    case FieldDescriptor::CPPTYPE_MESSAGE:
      if (f->message_type()->file()->package() == "google.protobuf") return std::nullopt;
      if (v.kind_case() != Value::kStructValue) return wrong();
      return check_message(v, f->message_type(), where + ".");
    case FieldDescriptor::CPPTYPE_ENUM: {
      const auto* e = f->enum_type();
      if (v.kind_case() == Value::kStringValue) {
        if (e->FindValueByName(v.string_value()) != nullptr) return std::nullopt;
        return where + ": \"" + v.string_value() + "\" is not a " + e->name() +
               "; valid: " + join(enum_names(e)) + did_you_mean(v.string_value(), enum_names(e));
      }
      if (is_number && v.kind_case() == Value::kNumberValue && std::floor(number) == number) {
        return std::nullopt;
      }
      return where + ": expects one of " + join(enum_names(e)) + ", got " + describe(v);
    }
    case FieldDescriptor::CPPTYPE_DOUBLE:
    case FieldDescriptor::CPPTYPE_FLOAT:
      return is_number ? std::nullopt : std::optional<std::string>(wrong());
    case FieldDescriptor::CPPTYPE_INT32:
    case FieldDescriptor::CPPTYPE_INT64:
    case FieldDescriptor::CPPTYPE_UINT32:
    case FieldDescriptor::CPPTYPE_UINT64: {
      const bool unsigned_type = f->cpp_type() == FieldDescriptor::CPPTYPE_UINT32 ||
                                 f->cpp_type() == FieldDescriptor::CPPTYPE_UINT64;
      if (!is_number || !std::isfinite(number) || std::floor(number) != number ||
          (unsigned_type && number < 0)) {
        return wrong();
      }
      const bool narrow = f->cpp_type() == FieldDescriptor::CPPTYPE_INT32 ||
                          f->cpp_type() == FieldDescriptor::CPPTYPE_UINT32;
      const double max = narrow ? (unsigned_type ? 4294967295.0 : 2147483647.0) : 9.2e18;
      const double min = unsigned_type ? 0.0 : (narrow ? -2147483648.0 : -9.2e18);
      if (number > max || number < min) {
        return where + ": " + describe(v) + " is out of range for " + wants(f) + " (" +
               std::string(f->cpp_type_name()) + ")";
      }
      return std::nullopt;
    }
    case FieldDescriptor::CPPTYPE_BOOL:
      return v.kind_case() == Value::kBoolValue ? std::nullopt
                                                : std::optional<std::string>(wrong());
    case FieldDescriptor::CPPTYPE_STRING:
      return v.kind_case() == Value::kStringValue ? std::nullopt
                                                  : std::optional<std::string>(wrong());
  }
  return std::nullopt;
}

std::optional<std::string> check_field(const FieldDescriptor* f, const Value& v,
                                       const std::string& where) {
  if (v.kind_case() == Value::kNullValue) return std::nullopt;
  if (f->is_map()) {
    if (v.kind_case() != Value::kStructValue) {
      return where + ": expects an object of key: value pairs, got " + describe(v);
    }
    const FieldDescriptor* value_field = f->message_type()->map_value();
    for (const auto& [key, item] : v.struct_value().fields()) {
      if (auto e = check_single(value_field, item, where + "[" + key + "]")) return e;
    }
    return std::nullopt;
  }
  if (f->is_repeated()) {
    if (v.kind_case() != Value::kListValue) {
      return where + ": expects a list of " + wants(f) + ", got " + describe(v);
    }
    const auto& items = v.list_value().values();
    for (int i = 0; i < items.size(); ++i) {
      if (auto e = check_single(f, items[i], where + "[" + std::to_string(i) + "]")) return e;
    }
    return std::nullopt;
  }
  return check_single(f, v, where);
}

std::optional<std::string> check_message(const Value& v, const Descriptor* type,
                                         const std::string& path) {
  if (v.kind_case() != Value::kStructValue) {
    return (path.empty() ? std::string("the file") : path.substr(0, path.size() - 1)) +
           ": expects an object (" + type->name() + "), got " + describe(v);
  }
  // In the file's order is unknown (a map): sorted keys give one answer every time.
  std::vector<std::string> keys;
  for (const auto& [key, item] : v.struct_value().fields()) keys.push_back(key);
  std::sort(keys.begin(), keys.end());
  std::vector<std::vector<std::string>> oneof_members(
      static_cast<std::size_t>(type->oneof_decl_count()));
  for (const auto& key : keys) {
    const FieldDescriptor* f = find_field(type, key);
    if (f == nullptr) return unknown_field(path, key, type);
    const Value& item = v.struct_value().fields().at(key);
    if (auto e = check_field(f, item, path + f->name())) return e;
    if (const auto* oneof = f->real_containing_oneof();
        oneof != nullptr && item.kind_case() != Value::kNullValue) {
      auto& members = oneof_members[static_cast<std::size_t>(oneof->index())];
      members.push_back(f->name());
      if (members.size() > 1) {
        return path + oneof->name() + ": give one of " + join(members, " or ") + ", not both";
      }
    }
  }
  return std::nullopt;
}

std::string value_text(const google::protobuf::Message& m, const FieldDescriptor* f) {
  const auto* r = m.GetReflection();
  char buf[64];
  switch (f->cpp_type()) {
    case FieldDescriptor::CPPTYPE_DOUBLE:
      std::snprintf(buf, sizeof buf, "%.6g", r->GetDouble(m, f));
      return buf;
    case FieldDescriptor::CPPTYPE_FLOAT:
      std::snprintf(buf, sizeof buf, "%.6g", static_cast<double>(r->GetFloat(m, f)));
      return buf;
    case FieldDescriptor::CPPTYPE_INT32:
      return std::to_string(r->GetInt32(m, f));
    case FieldDescriptor::CPPTYPE_INT64:
      return std::to_string(r->GetInt64(m, f));
    case FieldDescriptor::CPPTYPE_UINT32:
      return std::to_string(r->GetUInt32(m, f));
    case FieldDescriptor::CPPTYPE_UINT64:
      return std::to_string(r->GetUInt64(m, f));
    case FieldDescriptor::CPPTYPE_BOOL:
      return r->GetBool(m, f) ? "true" : "false";
    case FieldDescriptor::CPPTYPE_STRING:
      return r->GetString(m, f);
    case FieldDescriptor::CPPTYPE_ENUM:
      return r->GetEnum(m, f)->name();
    case FieldDescriptor::CPPTYPE_MESSAGE:
      return r->HasField(m, f) ? r->GetMessage(m, f).ShortDebugString() : "-";
  }
  return "-";
}

}  // namespace

std::size_t edit_distance(const std::string& a_in, const std::string& b_in) {
  const std::string a = lower(a_in), b = lower(b_in);
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

std::optional<std::string> closest(const std::string& given,
                                   const std::vector<std::string>& candidates) {
  const std::string* best = nullptr;
  std::size_t best_distance = std::numeric_limits<std::size_t>::max();
  for (const auto& c : candidates) {
    const std::size_t d = edit_distance(given, c);
    if (d < best_distance) {
      best = &c;
      best_distance = d;
    }
  }
  // Close enough to be a typo: a third of the word, at least two edits (swapped letters).
  const std::size_t allowed = std::max<std::size_t>(2, given.size() / 3);
  if (best == nullptr || best_distance == 0 || best_distance > allowed) return std::nullopt;
  return *best;
}

std::string did_you_mean(const std::string& given, const std::vector<std::string>& candidates) {
  const auto best = closest(given, candidates);
  return best ? ", did you mean " + *best + "?" : "";
}

std::optional<std::string> explain_json_error(const std::string& json, const Descriptor* type) {
  Value value;
  if (!google::protobuf::util::JsonStringToMessage(json, &value).ok()) return std::nullopt;
  return check_message(value, type, "");
}

std::vector<const FieldDescriptor*> resolve_field_path(const Descriptor* root,
                                                       const std::string& path,
                                                       const std::string& option) {
  std::vector<const FieldDescriptor*> out;
  const Descriptor* type = root;
  std::size_t start = 0;
  std::string walked;
  for (;;) {
    const std::size_t dot = path.find('.', start);
    const std::string part = path.substr(start, dot == std::string::npos ? dot : dot - start);
    if (type == nullptr) {
      usage_error("--" + option + ": '" + path + "': " + walked + " is not a message");
    }
    const FieldDescriptor* f = find_field(type, part);
    if (f == nullptr) {
      usage_error("--" + option + ": '" + path + "': " + unknown_field(walked, part, type));
    }
    if (f->is_repeated())
      usage_error("--" + option + ": '" + path + "': " + f->name() + " is a list");
    out.push_back(f);
    walked += f->name() + ".";
    type = f->cpp_type() == FieldDescriptor::CPPTYPE_MESSAGE ? f->message_type() : nullptr;
    if (dot == std::string::npos) break;
    start = dot + 1;
  }
  return out;
}

std::string field_path_value(const google::protobuf::Message& root,
                             const std::vector<const FieldDescriptor*>& path) {
  const google::protobuf::Message* m = &root;
  for (std::size_t i = 0; i + 1 < path.size(); ++i) {
    const auto* r = m->GetReflection();
    if (path[i]->real_containing_oneof() != nullptr && !r->HasField(*m, path[i])) return "-";
    m = &r->GetMessage(*m, path[i]);
  }
  const FieldDescriptor* last = path.back();
  if (last->real_containing_oneof() != nullptr && !m->GetReflection()->HasField(*m, last)) {
    return "-";
  }
  return value_text(*m, last);
}

}  // namespace softshock::cli
