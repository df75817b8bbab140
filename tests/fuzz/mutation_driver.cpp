// An in-tree mutation fuzzer for LLVMFuzzerTestOneInput (g++ has no libFuzzer): seeds from
// files (spec JSON, grid JSON) and built-in result-RPC requests, mutated by byte edits, splices
// and JSON-aware substitutions of extreme numbers and tokens. No coverage feedback: inputs that
// parse are kept in a bounded pool and mutated further, which keeps most executions deep in the
// pipeline. Deterministic for a given --seed. Exit 0 after the runs; a finding aborts (the
// sanitizers abort on their reports too), and the input is written to --crash-file first.
//
//   softshock_fuzz [--runs N] [--max-seconds S] [--seed X] [--crash-file PATH]
//                  [--spec FILE]... [--grid FILE]...
//   softshock_fuzz --meshes [--runs N] [--max-seconds S] [--seed X] [--crash-file PATH]
//
// --meshes fuzzes the mesh uploads alone (path 12): built-in MSH 2.2 and 4.1 files, ASCII and
// binary, mutated line-wise -- a count, a tag or a coordinate swapped for an extreme number
// (2^63 - 1, -1, 2^64 - 1, 1.5e8, ...), lines dropped, repeated or swapped, the file cut short --
// and byte-wise. Each execution is one upload checked by a child process, ~10/s.
#include <chrono>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "softshock/v1/service.pb.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);
extern "C" void softshock_fuzz_depth(long long* parsed, long long* valid);
extern "C" void softshock_fuzz_mesh_outcomes(long long* stored, long long* refused,
                                             long long* checker_crashes);

namespace {

using Input = std::string;  // byte 0: the path (see fuzz_target.cpp), then the payload

const std::vector<std::string>& tokens() {
  static const std::vector<std::string> t = {
      "1e308",
      "-1e308",
      "1e-320",
      "-0",
      "0",
      "NaN",
      "\"NaN\"",
      "\"Infinity\"",
      "\"-Infinity\"",
      "2147483647",
      "2147483648",
      "-2147483649",
      "9007199254740993",
      "18446744073709551616",
      "1e400",
      "null",
      "true",
      "[]",
      "{}",
      "\"\"",
      "\"../../etc/passwd\"",
      "\"/etc/passwd\"",
      "\"a.msh\\u0000x\"",
      "1000000",
      "0.5",
      "1e-12",
      "-1",
      "\"SQUARE\"",
      "\"GAUSSIAN\"",
      "99",
      "{\"disk\":{\"radius\":1e-12}}",
      "{\"mesh_file\":\"x.msh\"}",
      "{\"name\":\"pbar\",\"linspace\":{\"start\":0,\"stop\":1e308,\"num\":3}}",
      "{\"name\":\"geometry.target_elements\",\"values\":[20,2e9]}"};
  return t;
}

class Mutator {
 public:
  explicit Mutator(uint64_t seed) : rng_(seed) {}

  std::size_t below(std::size_t n) { return n == 0 ? 0 : rng_() % n; }

  Input mutate(const Input& in, const std::vector<Input>& pool) {
    Input out = in.empty() ? Input(1, '\0') : in;
    // JSON payloads mostly get edits that keep them JSON (a number or a value swapped for an
    // extreme one), so most executions get past the parser.
    const bool json = out.size() > 1 && out[1] == '{';
    if (json && below(4) != 0) {
      const int edits = 1 + static_cast<int>(below(3));
      for (int e = 0; e < edits; ++e) {
        if (below(2) == 0) {
          replace_number(out);
        } else {
          replace_value(out);
        }
      }
      return out;
    }
    const int edits = 1 + static_cast<int>(below(2));
    for (int e = 0; e < edits; ++e) {
      const std::size_t n = out.size();
      switch (below(9)) {
        case 0:  // flip a bit of the payload
          if (n > 1) out[1 + below(n - 1)] ^= static_cast<char>(1u << below(8));
          break;
        case 1:  // a random byte
          if (n > 1) out[1 + below(n - 1)] = static_cast<char>(below(256));
          break;
        case 2:  // insert a random byte
          out.insert(out.begin() + 1 + static_cast<std::ptrdiff_t>(below(n)),
                     static_cast<char>(below(256)));
          break;
        case 3:  // delete a range
          if (n > 2) {
            const std::size_t at = 1 + below(n - 1),
                              len = 1 + below(std::min<std::size_t>(16, n - at));
            out.erase(at, len);
          }
          break;
        case 4:  // duplicate a range
          if (n > 2) {
            const std::size_t at = 1 + below(n - 1),
                              len = 1 + below(std::min<std::size_t>(64, n - at));
            out.insert(at, out.substr(at, len));
          }
          break;
        case 5:  // splice with another pool entry
          if (!pool.empty()) {
            const Input& other = pool[below(pool.size())];
            if (other.size() > 1 && n > 1) {
              out.resize(1 + below(n - 1));
              out.append(other, 1 + below(other.size() - 1));
            }
          }
          break;
        case 6:  // replace a JSON number with an extreme one
          replace_number(out);
          break;
        case 7:  // insert a token
          out.insert(1 + below(n), tokens()[below(tokens().size())]);
          break;
        default:  // another path now and then (a payload meant for one, read by another)
          if (below(8) == 0) out[0] = static_cast<char>(below(12));
          break;
      }
    }
    if (out.size() > 64 * 1024) out.resize(64 * 1024);
    return out;
  }

 private:
  // The value after a ':' (up to the next ',' or '}' at the same level, roughly) becomes a
  // token: a number, a string, an object where a number was expected, ...
  void replace_value(Input& s) {
    std::vector<std::size_t> colons;
    for (std::size_t i = 1; i < s.size(); ++i) {
      if (s[i] == ':') colons.push_back(i);
    }
    if (colons.empty()) return;
    const std::size_t at = colons[below(colons.size())] + 1;
    std::size_t end = at;
    int depth = 0;
    bool in_string = false;
    for (; end < s.size(); ++end) {
      const char c = s[end];
      if (in_string) {
        if (c == '\\')
          ++end;
        else if (c == '"')
          in_string = false;
        continue;
      }
      if (c == '"')
        in_string = true;
      else if (c == '{' || c == '[')
        ++depth;
      else if ((c == '}' || c == ']') && depth-- == 0)
        break;
      else if (c == ',' && depth == 0)
        break;
    }
    s.replace(at, end - at, tokens()[below(tokens().size())]);
  }

  void replace_number(Input& s) {
    std::vector<std::pair<std::size_t, std::size_t>> numbers;
    for (std::size_t i = 1; i < s.size();) {
      if ((s[i] >= '0' && s[i] <= '9') || s[i] == '-') {
        std::size_t j = i + 1;
        while (j < s.size() && (std::isdigit(static_cast<unsigned char>(s[j])) || s[j] == '.' ||
                                s[j] == 'e' || s[j] == 'E' || s[j] == '-' || s[j] == '+')) {
          ++j;
        }
        numbers.emplace_back(i, j - i);
        i = j;
      } else {
        ++i;
      }
    }
    if (numbers.empty()) return;
    const auto [at, len] = numbers[below(numbers.size())];
    s.replace(at, len, tokens()[below(20)]);
  }

  std::mt19937_64 rng_;
};

constexpr char kMeshPath = 12;  // fuzz_target.cpp's mesh-upload path

// Numbers that broke or could break a mesh reader: tags past 2^63, negative tags and counts,
// counts far beyond the file, 32-bit edges, non-finite coordinates.
const std::vector<std::string>& msh_numbers() {
  static const std::vector<std::string> t = {"9223372036854775807",
                                             "-1",
                                             "18446744073709551615",
                                             "9223372036854775808",
                                             "0",
                                             "150000000",
                                             "2147483647",
                                             "2147483648",
                                             "4294967296",
                                             "-2147483649",
                                             "1e308",
                                             "-1e308",
                                             "nan",
                                             "inf",
                                             "1e-320",
                                             "99999999999999999999999",
                                             "3",
                                             "4",
                                             "5",
                                             "15",
                                             "2"};
  return t;
}

// Line-wise and byte-wise edits of an MSH payload (after the path byte).
class MshMutator {
 public:
  explicit MshMutator(std::mt19937_64& rng) : rng_(rng) {}
  std::size_t below(std::size_t n) { return n == 0 ? 0 : rng_() % n; }

  Input mutate(const Input& in) {
    std::string body = in.size() > 1 ? in.substr(1) : std::string();
    const int edits = 1 + static_cast<int>(below(3));
    for (int e = 0; e < edits; ++e) {
      std::vector<std::string> lines = split(body);
      switch (below(8)) {
        case 0:
        case 1:
        case 2: {  // a number swapped for an extreme one
          std::vector<std::pair<std::size_t, std::size_t>> numbers;
          for (std::size_t i = 0; i < body.size();) {
            if (std::isdigit(static_cast<unsigned char>(body[i])) || body[i] == '-') {
              std::size_t j = i + 1;
              while (j < body.size() &&
                     (std::isdigit(static_cast<unsigned char>(body[j])) || body[j] == '.' ||
                      body[j] == 'e' || body[j] == '-' || body[j] == '+')) {
                ++j;
              }
              numbers.emplace_back(i, j - i);
              i = j;
            } else {
              ++i;
            }
          }
          if (!numbers.empty()) {
            const auto [at, len] = numbers[below(numbers.size())];
            body.replace(at, len, msh_numbers()[below(msh_numbers().size())]);
          }
          break;
        }
        case 3:  // a line dropped
          if (!lines.empty()) lines.erase(lines.begin() + below(lines.size()));
          body = join(lines);
          break;
        case 4:  // a line repeated
          if (!lines.empty()) {
            const std::size_t k = below(lines.size());
            lines.insert(lines.begin() + k, lines[k]);
          }
          body = join(lines);
          break;
        case 5:  // two lines swapped
          if (lines.size() > 1) std::swap(lines[below(lines.size())], lines[below(lines.size())]);
          body = join(lines);
          break;
        case 6:  // cut short
          body.resize(below(body.size() + 1));
          break;
        default:  // a byte changed
          if (!body.empty()) body[below(body.size())] = static_cast<char>(below(256));
          break;
      }
    }
    if (body.size() > 256 * 1024) body.resize(256 * 1024);
    Input out(1, kMeshPath);
    out += body;
    return out;
  }

 private:
  static std::vector<std::string> split(const std::string& s) {
    std::vector<std::string> out;
    std::size_t start = 0;
    while (start < s.size()) {
      const std::size_t end = s.find('\n', start);
      out.push_back(s.substr(start, end == std::string::npos ? std::string::npos : end - start));
      if (end == std::string::npos) break;
      start = end + 1;
    }
    return out;
  }
  static std::string join(const std::vector<std::string>& lines) {
    std::string out;
    for (const auto& l : lines) out += l + "\n";
    return out;
  }
  std::mt19937_64& rng_;
};

// MSH seeds: a unit square of n x n cells, two triangles each, in MSH 2.2 and 4.1, ASCII and
// binary, plus the line and point elements Gmsh writes for the boundary.
std::vector<Input> msh_seeds() {
  std::vector<Input> out;
  auto tag = [](const std::string& body) {
    Input in(1, kMeshPath);
    in += body;
    return in;
  };
  const int n = 3;
  const int nodes = (n + 1) * (n + 1), triangles = 2 * n * n;
  auto node_xyz = [&](int k, double* xyz) {
    xyz[0] = (k % (n + 1)) * 1e-5, xyz[1] = (k / (n + 1)) * 1e-5, xyz[2] = 0;
  };
  auto corners = [&](int t, int* c) {  // 1-based node tags of triangle t
    const int cell = t / 2, i = cell % n, j = cell / n, a = j * (n + 1) + i + 1;
    if (t % 2 == 0)
      c[0] = a, c[1] = a + 1, c[2] = a + n + 2;
    else
      c[0] = a, c[1] = a + n + 2, c[2] = a + n + 1;
  };
  {  // MSH 2.2 ASCII
    std::ostringstream s;
    s << "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n2 1 \"gel\"\n$EndPhysicalNames\n"
      << "$Nodes\n"
      << nodes << "\n";
    for (int k = 0; k < nodes; ++k) {
      double xyz[3];
      node_xyz(k, xyz);
      s << k + 1 << " " << xyz[0] << " " << xyz[1] << " " << xyz[2] << "\n";
    }
    s << "$EndNodes\n$Elements\n" << triangles + 1 << "\n1 15 2 0 1 1\n";
    for (int t = 0; t < triangles; ++t) {
      int c[3];
      corners(t, c);
      s << t + 2 << " 2 2 1 1 " << c[0] << " " << c[1] << " " << c[2] << "\n";
    }
    s << "$EndElements\n";
    out.push_back(tag(s.str()));
  }
  {  // MSH 4.1 ASCII, with an $Entities section
    std::ostringstream s;
    s << "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Entities\n0 0 1 0\n1 0 0 0 3e-5 3e-5 0 0 0\n"
      << "$EndEntities\n$Nodes\n1 " << nodes << " 1 " << nodes << "\n2 1 0 " << nodes << "\n";
    for (int k = 0; k < nodes; ++k) s << k + 1 << "\n";
    for (int k = 0; k < nodes; ++k) {
      double xyz[3];
      node_xyz(k, xyz);
      s << xyz[0] << " " << xyz[1] << " " << xyz[2] << "\n";
    }
    s << "$EndNodes\n$Elements\n1 " << triangles << " 1 " << triangles << "\n2 1 2 " << triangles
      << "\n";
    for (int t = 0; t < triangles; ++t) {
      int c[3];
      corners(t, c);
      s << t + 1 << " " << c[0] << " " << c[1] << " " << c[2] << "\n";
    }
    s << "$EndElements\n";
    out.push_back(tag(s.str()));
  }
  {  // MSH 4.1 binary
    std::string b = "$MeshFormat\n4.1 1 8\n";
    const int one = 1;
    b.append(reinterpret_cast<const char*>(&one), 4);
    b += "\n$EndMeshFormat\n$Nodes\n";
    auto put_size = [&](uint64_t v) { b.append(reinterpret_cast<const char*>(&v), 8); };
    auto put_int = [&](int32_t v) { b.append(reinterpret_cast<const char*>(&v), 4); };
    put_size(1), put_size(nodes), put_size(1), put_size(nodes);
    put_int(2), put_int(1), put_int(0), put_size(nodes);
    for (int k = 0; k < nodes; ++k) put_size(k + 1);
    for (int k = 0; k < nodes; ++k) {
      double xyz[3];
      node_xyz(k, xyz);
      b.append(reinterpret_cast<const char*>(xyz), sizeof xyz);
    }
    b += "\n$EndNodes\n$Elements\n";
    put_size(1), put_size(triangles), put_size(1), put_size(triangles);
    put_int(2), put_int(1), put_int(2), put_size(triangles);
    for (int t = 0; t < triangles; ++t) {
      int c[3];
      corners(t, c);
      put_size(t + 1), put_size(c[0]), put_size(c[1]), put_size(c[2]);
    }
    b += "\n$EndElements\n";
    out.push_back(tag(b));
  }
  return out;
}

// The path byte, then the payload (appended: GCC 12 warns falsely on string + string here).
Input tagged(char path, const std::string& payload) {
  Input out(1, path);
  out.append(payload);
  return out;
}

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    std::cerr << "softshock_fuzz: cannot read " << path << "\n";
    std::exit(2);
  }
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// Result-RPC requests as seeds (paths 7..11).
std::vector<Input> request_seeds() {
  using namespace softshock::v1;
  std::vector<Input> out;
  auto add = [&](char path, const google::protobuf::Message& m) {
    out.push_back(tagged(path, m.SerializeAsString()));
  };
  GetTimeSeriesRequest ts;
  ts.set_id("fuzzjob");
  ts.add_names("abar");
  ts.add_names("abar");
  ts.set_every(3);
  add(7, ts);
  GetModesRequest modes;
  modes.set_id("jobs/fuzzjob");
  modes.set_mode_min(2);
  modes.set_mode_max(5);
  modes.set_every(2);
  add(8, modes);
  ListJobsRequest list;
  list.set_page_size(10);
  list.set_label("suite=x");
  list.mutable_created_after()->set_seconds(1700000000);
  add(9, list);
  QueryJobsRequest query;
  auto* filter = query.add_filters();
  filter->set_name("pbar");
  filter->set_gt(0.5);
  query.set_order_by("max_abar desc");
  add(10, query);
  GetGridReductionRequest reduction;
  reduction.set_id("grids/abc");
  reduction.set_quantity("abar_at");
  reduction.set_tbar(2);
  add(11, reduction);
  return out;
}

Input g_current;
std::string g_crash_file = "softshock_fuzz_crash.bin";

// Keeps the input that took the process down (an abort from a sanitizer or the target).
extern "C" void on_abort(int) {
  if (FILE* f = std::fopen(g_crash_file.c_str(), "wb")) {
    std::fwrite(g_current.data(), 1, g_current.size(), f);
    std::fclose(f);
  }
  std::signal(SIGABRT, SIG_DFL);
  std::abort();
}

}  // namespace

int main(int argc, char** argv) {
  long long runs = 10000;
  double max_seconds = 0;
  uint64_t seed = 1;
  std::vector<Input> seeds;
  bool meshes = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::cerr << "softshock_fuzz: " << a << " needs a value\n";
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--runs") {
      runs = std::stoll(next());
    } else if (a == "--max-seconds") {
      max_seconds = std::stod(next());
    } else if (a == "--seed") {
      seed = std::stoull(next());
    } else if (a == "--crash-file") {
      g_crash_file = next();
    } else if (a == "--spec") {
      seeds.push_back(tagged(0, read_file(next())));
    } else if (a == "--grid") {
      seeds.push_back(tagged(6, read_file(next())));
    } else if (a == "--meshes") {
      meshes = true;
    } else {
      std::cerr << "usage: softshock_fuzz [--runs N] [--max-seconds S] [--seed X] "
                   "[--crash-file PATH] [--spec FILE]... [--grid FILE]...\n"
                   "       softshock_fuzz --meshes [--runs N] [--max-seconds S] [--seed X] "
                   "[--crash-file PATH]\n";
      return 2;
    }
  }
  if (meshes) {
    seeds = msh_seeds();
  } else {
    for (auto& r : request_seeds()) seeds.push_back(std::move(r));
    seeds.push_back(tagged(0, "{}"));
  }
  std::signal(SIGABRT, on_abort);

  // Each seed runs once as is (this also builds the target's fixture before the clock starts).
  for (const auto& s : seeds) {
    g_current = s;
    LLVMFuzzerTestOneInput(reinterpret_cast<const uint8_t*>(s.data()), s.size());
  }
  Mutator mutator(seed);
  std::mt19937_64 msh_rng(seed);
  MshMutator msh_mutator(msh_rng);
  std::vector<Input> pool = seeds;
  constexpr std::size_t kPool = 512;
  const auto start = std::chrono::steady_clock::now();
  long long done = 0;
  for (; done < runs; ++done) {
    if (max_seconds > 0 && (meshes || (done & 255) == 0) &&
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() >
            max_seconds) {
      break;
    }
    // Mostly from the pool of mutants, sometimes back to a pristine seed.
    const Input& parent = mutator.below(4) == 0 ? seeds[mutator.below(seeds.size())]
                                                : pool[mutator.below(pool.size())];
    g_current = meshes ? msh_mutator.mutate(parent) : mutator.mutate(parent, pool);
    long long parsed_before = 0, parsed_after = 0, valid_before = 0, valid_after = 0;
    softshock_fuzz_depth(&parsed_before, &valid_before);
    LLVMFuzzerTestOneInput(reinterpret_cast<const uint8_t*>(g_current.data()), g_current.size());
    softshock_fuzz_depth(&parsed_after, &valid_after);
    // Keep inputs that still parse, so depth is not lost to garbage (meshes: every accepted one
    // and a quarter of the refused, so mutations pile up).
    const bool keep =
        meshes ? valid_after > valid_before || mutator.below(4) == 0 : parsed_after > parsed_before;
    if (keep) {
      if (pool.size() < kPool) {
        pool.push_back(g_current);
      } else {
        pool[mutator.below(kPool)] = g_current;
      }
    }
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  long long parsed = 0, valid = 0;
  softshock_fuzz_depth(&parsed, &valid);
  if (meshes) {
    long long stored = 0, refused = 0, crashes = 0;
    softshock_fuzz_mesh_outcomes(&stored, &refused, &crashes);
    std::printf(
        "softshock_fuzz --meshes: %lld uploads in %.1f s (%.1f/s), seed %llu, 0 crashes of the "
        "store; %lld stored, %lld refused (%lld of them crashed or exhausted the checker child)\n",
        done + static_cast<long long>(seeds.size()), seconds, done / std::max(seconds, 1e-9),
        static_cast<unsigned long long>(seed), stored, refused, crashes);
    return 0;
  }
  std::printf(
      "softshock_fuzz: %lld executions in %.1f s (%.0f/s), seed %llu, 0 crashes; %lld parsed, "
      "%lld valid specs or OK answers (seeds included)\n",
      done, seconds, done / std::max(seconds, 1e-9), static_cast<unsigned long long>(seed), parsed,
      valid);
  return 0;
}
