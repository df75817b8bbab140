// Spec files explained in words, from the schema itself (the protobuf descriptors of RunSpec and
// SubmitGridRequest): a misspelt field gets "did you mean" (the closest names at that level by
// edit distance), a value of the wrong type is named as a person would ("expects a number, got
// text"), an enum's valid values are listed. Used where protobuf's own JSON parser refused a file
// (its messages say "Cannot find field." or "TYPE_DOUBLE"), and by `list --fields` to resolve
// spec field paths.
#pragma once

#include <google/protobuf/descriptor.h>
#include <google/protobuf/message.h>

#include <optional>
#include <string>
#include <vector>

namespace softshock::cli {

// Levenshtein distance (insertions, deletions, substitutions), case-insensitive.
std::size_t edit_distance(const std::string& a, const std::string& b);

// The candidate closest to `given` when it is close enough to be a typo (within a third of its
// length, at least 2 edits), else nullopt. Exact matches are not typos: nullopt.
std::optional<std::string> closest(const std::string& given,
                                   const std::vector<std::string>& candidates);
// ", did you mean X?" with closest()'s X, or "".
std::string did_you_mean(const std::string& given, const std::vector<std::string>& candidates);

// The first problem protobuf's JSON mapping would have with `json` as a `type` message, in words:
// "geometry.disk.radus: no such field in Disk; did you mean radius? (fields: radius)". `prefix`
// goes before the path ("" or "base_spec."). nullopt when the text is not JSON at all or the
// walk finds nothing (the caller then keeps protobuf's own message).
std::optional<std::string> explain_json_error(const std::string& json,
                                              const google::protobuf::Descriptor* type);

// A dotted field path ("material.shear_viscosity", proto or JSON spelling) under `root`, each
// step a message field but the last. Throws a usage error naming the path, with did-you-mean.
std::vector<const google::protobuf::FieldDescriptor*> resolve_field_path(
    const google::protobuf::Descriptor* root, const std::string& path, const std::string& option);

// The value at a resolved path as text ("0.25", "SQUARE", "-" for an unset message or oneof
// member, lists joined by ';').
std::string field_path_value(const google::protobuf::Message& root,
                             const std::vector<const google::protobuf::FieldDescriptor*>& path);

}  // namespace softshock::cli
