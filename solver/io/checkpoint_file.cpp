// Checkpoint files (checkpoint_file.hpp). Layout, little-endian:
//   "SSCKPT\0\n" | u32 0x01020304 (byte order) | u32 format
//   records: u32 name length (1..255) | name | u8 type | u64 count | count values
//     types: 1 f64, 2 f32, 3 i64, 4 bytes (a string)
//   end: u32 0 | u64 checksum of every byte before this end record
// Records are looked up by name, so a later format can add some; a reader of format 1 needs the
// ones write_checkpoint writes and refuses a file missing any.
#include "solver/io/checkpoint_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "solver/io/durable_file.hpp"
#include "solver/run_summary.hpp"

namespace softshock {

namespace fs = std::filesystem;

namespace {

constexpr char kMagic[8] = {'S', 'S', 'C', 'K', 'P', 'T', '\0', '\n'};
constexpr std::uint32_t kByteOrder = 0x01020304;
constexpr std::size_t kMaxName = 255;
enum Type : std::uint8_t { kF64 = 1, kF32 = 2, kI64 = 3, kBytes = 4 };
std::size_t type_bytes(std::uint8_t t) {
  return t == kF64 || t == kI64 ? 8 : t == kF32 ? 4 : t == kBytes ? 1 : 0;
}

std::uint64_t avalanche(std::uint64_t h) {  // MurmurHash3's finaliser
  h ^= h >> 33;
  h *= 0xff51afd7ed558ccdull;
  h ^= h >> 33;
  h *= 0xc4ceb9fe1a85ec53ull;
  h ^= h >> 33;
  return h;
}

// Buffered writes to a file descriptor, checksummed as they go.
class RecordWriter {
 public:
  explicit RecordWriter(const fs::path& path) : path_(path) {
    fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd_ < 0) fail("cannot create");
    buffer_.reserve(kBufferBytes);
  }
  ~RecordWriter() {
    if (fd_ >= 0) ::close(fd_);
  }
  RecordWriter(const RecordWriter&) = delete;
  RecordWriter& operator=(const RecordWriter&) = delete;

  void raw(const void* data, std::size_t bytes, bool checksummed = true) {
    if (checksummed) checksum_.update(data, bytes);
    if (buffer_.size() + bytes > kBufferBytes) flush();
    if (bytes >= kBufferBytes) {
      put(data, bytes);
    } else {
      const auto* p = static_cast<const char*>(data);
      buffer_.insert(buffer_.end(), p, p + bytes);
    }
  }
  template <typename T>
  void value(T v) {
    raw(&v, sizeof v);
  }
  void record(const std::string& name, Type type, const void* data, std::size_t count) {
    value(static_cast<std::uint32_t>(name.size()));
    raw(name.data(), name.size());
    value(static_cast<std::uint8_t>(type));
    value(static_cast<std::uint64_t>(count));
    raw(data, count * type_bytes(type));
  }
  void f64(const std::string& name, const std::vector<double>& v) {
    record(name, kF64, v.data(), v.size());
  }
  void f64(const std::string& name, double v) { record(name, kF64, &v, 1); }
  void i64(const std::string& name, std::int64_t v) { record(name, kI64, &v, 1); }
  void i64s(const std::string& name, const std::vector<std::int64_t>& v) {
    record(name, kI64, v.data(), v.size());
  }
  void text(const std::string& name, const std::string& s) {
    record(name, kBytes, s.data(), s.size());
  }
  // The end record, then the data on the disk (fsync) and the descriptor closed.
  void finish() {
    const std::uint64_t sum = checksum_.value();  // of every byte before the end record
    const std::uint32_t end = 0;
    raw(&end, sizeof end, false);
    raw(&sum, sizeof sum, false);
    flush();
    if (::fsync(fd_) != 0) fail("cannot fsync");
    const int fd = fd_;
    fd_ = -1;
    if (::close(fd) != 0) fail("cannot close");
  }

 private:
  static constexpr std::size_t kBufferBytes = 1 << 20;
  [[noreturn]] void fail(const char* what) const {
    throw std::runtime_error(std::string(what) + " " + path_.string() + ": " +
                             std::strerror(errno));
  }
  void put(const void* data, std::size_t bytes) {
    const auto* p = static_cast<const char*>(data);
    while (bytes > 0) {
      const ssize_t n = ::write(fd_, p, bytes);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) fail("cannot write");
      p += n, bytes -= static_cast<std::size_t>(n);
    }
  }
  void flush() {
    put(buffer_.data(), buffer_.size());
    buffer_.clear();
  }

  fs::path path_;
  int fd_ = -1;
  std::vector<char> buffer_;
  CheckpointChecksum checksum_;
};

struct Record {
  std::uint8_t type = 0;
  std::size_t offset = 0, count = 0;
};

// A parsed, verified file: the bytes and where each record's values are.
class RecordReader {
 public:
  explicit RecordReader(const std::string& path) : path_(path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw CheckpointError("cannot open checkpoint " + path + ": " + std::strerror(errno));
    std::ostringstream all;
    all << in.rdbuf();
    bytes_ = std::move(all).str();
    std::size_t at = 0;
    auto take = [&](void* out, std::size_t n) {
      if (bytes_.size() - at < n) bad("truncated");
      std::memcpy(out, bytes_.data() + at, n);
      at += n;
    };
    char magic[8];
    take(magic, sizeof magic);
    if (std::memcmp(magic, kMagic, sizeof magic) != 0) bad("not a softshock checkpoint");
    std::uint32_t order = 0, format = 0;
    take(&order, sizeof order);
    if (order != kByteOrder) bad("written on a machine of another byte order");
    take(&format, sizeof format);
    if (format != static_cast<std::uint32_t>(kCheckpointFormat)) {
      bad("format " + std::to_string(format) + ", this softshock reads format " +
          std::to_string(kCheckpointFormat));
    }
    for (;;) {
      const std::size_t record_start = at;
      std::uint32_t name_length = 0;
      take(&name_length, sizeof name_length);
      if (name_length == 0) {
        std::uint64_t stored = 0;
        take(&stored, sizeof stored);
        CheckpointChecksum sum;
        sum.update(bytes_.data(), record_start);
        if (sum.value() != stored) bad("checksum mismatch (the file was altered or half-written)");
        if (at != bytes_.size()) bad("bytes after the end record");
        break;
      }
      if (name_length > kMaxName) bad("a record name of " + std::to_string(name_length) + " bytes");
      std::string name(name_length, '\0');
      take(name.data(), name_length);
      Record r;
      std::uint64_t count = 0;
      take(&r.type, sizeof r.type);
      take(&count, sizeof count);
      const std::size_t size = type_bytes(r.type);
      if (size == 0) bad("record " + name + " of unknown type " + std::to_string(r.type));
      if (count > (bytes_.size() - at) / size) bad("truncated in record " + name);
      r.offset = at, r.count = static_cast<std::size_t>(count);
      at += r.count * size;
      records_[name] = r;
    }
  }

  const Record& find(const std::string& name, std::uint8_t type) const {
    const auto it = records_.find(name);
    if (it == records_.end()) bad("no record " + name);
    if (it->second.type != type) bad("record " + name + " has another type");
    return it->second;
  }
  bool has(const std::string& name) const { return records_.count(name) > 0; }
  template <typename T>
  std::vector<T> array(const std::string& name, std::uint8_t type) const {
    const Record& r = find(name, type);
    std::vector<T> out(r.count);
    if (r.count > 0) std::memcpy(out.data(), bytes_.data() + r.offset, r.count * sizeof(T));
    return out;
  }
  std::vector<double> f64s(const std::string& name) const { return array<double>(name, kF64); }
  std::vector<float> f32s(const std::string& name) const { return array<float>(name, kF32); }
  std::vector<std::int64_t> i64s(const std::string& name) const {
    return array<std::int64_t>(name, kI64);
  }
  double f64(const std::string& name) const { return one(f64s(name), name); }
  std::int64_t i64(const std::string& name) const { return one(i64s(name), name); }
  std::string text(const std::string& name) const {
    const Record& r = find(name, kBytes);
    return bytes_.substr(r.offset, r.count);
  }
  // Names of the records under a prefix, in name order.
  std::vector<std::string> names(const std::string& prefix) const {
    std::vector<std::string> out;
    for (auto it = records_.lower_bound(prefix);
         it != records_.end() && it->first.compare(0, prefix.size(), prefix) == 0; ++it)
      out.push_back(it->first);
    return out;
  }
  std::uint8_t type(const std::string& name) const { return records_.at(name).type; }

  [[noreturn]] void bad(const std::string& why) const {
    throw CheckpointError("checkpoint " + path_ + " is unusable: " + why);
  }

 private:
  template <typename T>
  T one(const std::vector<T>& v, const std::string& name) const {
    if (v.size() != 1) bad("record " + name + " is not one value");
    return v[0];
  }

  std::string path_;
  std::string bytes_;
  std::map<std::string, Record> records_;
};

// Rows of equal length as one row-major array.
std::vector<double> flatten(const std::vector<std::vector<double>>& rows, std::size_t& cols) {
  cols = rows.empty() ? 0 : rows.front().size();
  std::vector<double> out;
  out.reserve(rows.size() * cols);
  for (const auto& row : rows) {
    if (row.size() != cols) throw std::invalid_argument("checkpoint: mode rows differ in length");
    out.insert(out.end(), row.begin(), row.end());
  }
  return out;
}

}  // namespace

void CheckpointChecksum::update(const void* data, std::size_t bytes) {
  if (bytes == 0) return;  // an empty vector's data() may be null, which memcpy must not see
  const auto* p = static_cast<const unsigned char*>(data);
  length_ += bytes;
  auto word = [this](const unsigned char* w) {
    std::uint64_t v;
    std::memcpy(&v, w, 8);
    hash_ = (hash_ ^ v) * 0x100000001b3ull;
  };
  if (pending_bytes_ > 0) {  // complete the word begun by an earlier piece
    const std::size_t n = std::min(bytes, sizeof pending_ - pending_bytes_);
    std::memcpy(pending_ + pending_bytes_, p, n);
    pending_bytes_ += n, p += n, bytes -= n;
    if (pending_bytes_ < sizeof pending_) return;
    word(pending_);
    pending_bytes_ = 0;
  }
  for (; bytes >= 8; p += 8, bytes -= 8) word(p);
  if (bytes > 0) std::memcpy(pending_, p, bytes);
  pending_bytes_ = bytes;
}

std::uint64_t CheckpointChecksum::value() const {
  std::uint64_t h = hash_;
  if (pending_bytes_ > 0) {
    unsigned char last[8] = {};
    std::memcpy(last, pending_, pending_bytes_);
    std::uint64_t v;
    std::memcpy(&v, last, 8);
    h = (h ^ v) * 0x100000001b3ull;
  }
  return avalanche(h ^ length_);
}

std::string mesh_fingerprint(const Mesh& mesh) {
  CheckpointChecksum sum;
  const std::uint64_t counts[] = {mesh.x.size(),
                                  mesh.y.size(),
                                  mesh.z.size(),
                                  mesh.triangles.size(),
                                  mesh.tetrahedra.size(),
                                  mesh.boundary_edges.size(),
                                  mesh.boundary_faces.size()};
  sum.update(counts, sizeof counts);
  for (const auto* v : {&mesh.x, &mesh.y, &mesh.z})
    sum.update(v->data(), v->size() * sizeof(double));
  sum.update(mesh.triangles.data(), mesh.triangles.size() * sizeof(mesh.triangles[0]));
  sum.update(mesh.tetrahedra.data(), mesh.tetrahedra.size() * sizeof(mesh.tetrahedra[0]));
  sum.update(mesh.boundary_edges.data(),
             mesh.boundary_edges.size() * sizeof(mesh.boundary_edges[0]));
  sum.update(mesh.boundary_faces.data(),
             mesh.boundary_faces.size() * sizeof(mesh.boundary_faces[0]));
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(sum.value()));
  return hex;
}

void write_checkpoint(const std::string& path, const Checkpoint& c) {
  const fs::path final_path(path);
  const fs::path tmp = final_path.string() + ".tmp";
  try {
    RecordWriter w(tmp);
    w.raw(kMagic, sizeof kMagic);
    w.value(kByteOrder);
    w.value(static_cast<std::uint32_t>(kCheckpointFormat));
    const CheckpointHeader& h = c.header;
    w.i64("header.solver_revision", h.solver_revision);
    w.text("header.solver_version", h.solver_version);
    w.text("header.spec", h.spec_json);
    w.text("header.mesh", h.mesh_fingerprint);
    std::string files;
    std::vector<std::int64_t> frames;
    for (const auto& s : h.segments) {
      if (s.file.find('\n') != std::string::npos)
        throw std::invalid_argument("checkpoint: a segment name with a newline");
      files += s.file + "\n";
      frames.push_back(static_cast<std::int64_t>(s.frames));
    }
    w.text("header.segments.files", files);
    w.i64s("header.segments.frames", frames);
    w.f64("header.frame_times", h.frame_times);

    const RunState& s = c.state;
    w.i64("loop.dimension", s.dimension);
    w.i64("loop.nodes", static_cast<std::int64_t>(s.nodes));
    w.i64("loop.elements", static_cast<std::int64_t>(s.elements));
    w.i64("loop.threads", s.threads);
    w.f64("loop.time_s", s.time_s);
    w.i64("loop.steps", s.steps);
    w.f64("loop.dt_stable_s", s.dt_stable_s);
    w.f64("loop.tiny_s", s.tiny_s);
    w.f64("loop.dissipated", s.dissipated);
    w.f64("loop.external_work", s.external_work);
    w.f64("loop.interval_min_dt_s", s.interval_min_dt_s);
    w.i64("loop.interval_min_element", s.interval_min_element);
    w.i64("loop.next_history", s.next_history);
    w.i64("loop.next_output", s.next_output);
    w.f64("loop.last_frame_time_s", s.last_frame_time_s);
    w.f64("loop.min_dt_s", s.min_dt_s);
    w.f64("loop.max_dt_s", s.max_dt_s);
    w.i64("loop.totals_sampled", s.totals_sampled ? 1 : 0);
    w.f64("loop.totals.min_step_sq", s.totals.min_step_sq);
    w.i64("loop.totals.min_step_element", s.totals.min_step_element);
    w.f64("loop.totals.dissipation", s.totals.dissipation);
    w.i64("loop.totals.bad_element", s.totals.bad_element);
    w.f64("loop.totals.bad_j", s.totals.bad_j);
    w.f64("loop.totals.element_energy", s.totals.element_energy);
    w.f64("loop.totals.max_aspect_ratio", s.totals.max_aspect_ratio);
    w.f64("loop.totals.nodal_energy", s.totals.nodal_energy);
    w.i64("loop.frames_written", static_cast<std::int64_t>(s.frames_written));
    w.f64("loop.wall_time_s", s.wall_time_s);
    w.f64("loop.kernel_time_s", s.kernel_time_s);
    w.f64("loop.diagnostics_time_s", s.diagnostics_time_s);
    w.f64("loop.output_time_s", s.output_time_s);
    w.f64("loop.pass_time_s", std::vector<double>(s.pass_time_s.begin(), s.pass_time_s.end()));
    w.i64("loop.stopped", s.stopped ? 1 : 0);

    w.i64("history.damage", s.history.damage ? 1 : 0);  // it decides which columns there are
    for (const auto& [name, column] : s.history.columns()) w.f64("history." + name, *column);
    std::size_t cols = 0;
    w.f64("history.modes", flatten(s.history.modes, cols));
    w.i64("history.modes.rows", static_cast<std::int64_t>(s.history.modes.size()));
    w.i64("history.modes.cols", static_cast<std::int64_t>(cols));
    w.f64("history.modes_z_mean", flatten(s.history.modes_z_mean, cols));
    w.i64("history.modes_z_mean.rows", static_cast<std::int64_t>(s.history.modes_z_mean.size()));
    w.i64("history.modes_z_mean.cols", static_cast<std::int64_t>(cols));

    // In name order, the order read_checkpoint gives them back: a file written again from what
    // was read is the same bytes.
    std::vector<const StateArray*> arrays;
    for (const auto& a : s.arrays) arrays.push_back(&a);
    std::sort(arrays.begin(), arrays.end(),
              [](const StateArray* a, const StateArray* b) { return a->name < b->name; });
    for (const StateArray* a : arrays) {
      if (a->single)
        w.record("state." + a->name, kF32, a->f32.data(), a->f32.size());
      else
        w.f64("state." + a->name, a->f64);
    }
    w.finish();
    rename_file(tmp, final_path);
    const fs::path dir = final_path.has_parent_path() ? final_path.parent_path() : fs::path(".");
    fsync_path(dir, true);
  } catch (...) {
    std::error_code ignored;
    fs::remove(tmp, ignored);
    throw;
  }
}

namespace {

std::vector<std::vector<double>> unflatten(const RecordReader& r, const std::string& name) {
  const auto flat = r.f64s(name);
  const auto rows = r.i64(name + ".rows"), cols = r.i64(name + ".cols");
  if (rows < 0 || cols < 0 ||
      static_cast<std::uint64_t>(rows) * static_cast<std::uint64_t>(cols) != flat.size())
    r.bad("record " + name + " is not rows x cols");
  std::vector<std::vector<double>> out(static_cast<std::size_t>(rows));
  for (std::size_t k = 0; k < out.size(); ++k)
    out[k].assign(flat.begin() + k * cols, flat.begin() + (k + 1) * cols);
  return out;
}

}  // namespace

Checkpoint read_checkpoint(const std::string& path) {
  const RecordReader r(path);
  Checkpoint c;
  CheckpointHeader& h = c.header;
  h.solver_revision = static_cast<int>(r.i64("header.solver_revision"));
  h.solver_version = r.text("header.solver_version");
  if (h.solver_revision != kSolverRevision) {
    r.bad("written by solver revision " + std::to_string(h.solver_revision) + " (softshock " +
          h.solver_version + "), this is revision " + std::to_string(kSolverRevision) +
          ": its state would not continue with the same numerics");
  }
  h.spec_json = r.text("header.spec");
  h.mesh_fingerprint = r.text("header.mesh");
  const std::string files = r.text("header.segments.files");
  const auto frames = r.i64s("header.segments.frames");
  std::size_t at = 0;
  for (const auto n : frames) {
    const auto end = files.find('\n', at);
    if (end == std::string::npos || n < 0) r.bad("the segment list does not parse");
    h.segments.push_back({files.substr(at, end - at), static_cast<std::size_t>(n)});
    at = end + 1;
  }
  if (at != files.size()) r.bad("the segment list does not parse");
  h.frame_times = r.f64s("header.frame_times");

  RunState& s = c.state;
  s.dimension = static_cast<int>(r.i64("loop.dimension"));
  s.nodes = static_cast<std::size_t>(r.i64("loop.nodes"));
  s.elements = static_cast<std::size_t>(r.i64("loop.elements"));
  s.threads = static_cast<int>(r.i64("loop.threads"));
  s.time_s = r.f64("loop.time_s");
  s.steps = r.i64("loop.steps");
  s.dt_stable_s = r.f64("loop.dt_stable_s");
  s.tiny_s = r.f64("loop.tiny_s");
  s.dissipated = r.f64("loop.dissipated");
  s.external_work = r.f64("loop.external_work");
  s.interval_min_dt_s = r.f64("loop.interval_min_dt_s");
  s.interval_min_element = r.i64("loop.interval_min_element");
  s.next_history = r.i64("loop.next_history");
  s.next_output = r.i64("loop.next_output");
  s.last_frame_time_s = r.f64("loop.last_frame_time_s");
  s.min_dt_s = r.f64("loop.min_dt_s");
  s.max_dt_s = r.f64("loop.max_dt_s");
  s.totals_sampled = r.i64("loop.totals_sampled") != 0;
  s.totals.min_step_sq = r.f64("loop.totals.min_step_sq");
  s.totals.min_step_element = r.i64("loop.totals.min_step_element");
  s.totals.dissipation = r.f64("loop.totals.dissipation");
  s.totals.bad_element = r.i64("loop.totals.bad_element");
  s.totals.bad_j = r.f64("loop.totals.bad_j");
  s.totals.element_energy = r.f64("loop.totals.element_energy");
  s.totals.max_aspect_ratio = r.f64("loop.totals.max_aspect_ratio");
  s.totals.nodal_energy = r.f64("loop.totals.nodal_energy");
  s.frames_written = static_cast<std::size_t>(r.i64("loop.frames_written"));
  s.wall_time_s = r.f64("loop.wall_time_s");
  s.kernel_time_s = r.f64("loop.kernel_time_s");
  s.diagnostics_time_s = r.f64("loop.diagnostics_time_s");
  s.output_time_s = r.f64("loop.output_time_s");
  const auto passes = r.f64s("loop.pass_time_s");
  if (passes.size() != s.pass_time_s.size()) r.bad("record loop.pass_time_s has another length");
  std::copy(passes.begin(), passes.end(), s.pass_time_s.begin());
  s.stopped = r.i64("loop.stopped") != 0;
  if (s.frames_written != h.frame_times.size()) r.bad("its frame count and frame times disagree");

  // columns() lists the History's own series (the damage ones with damage); they belong to `s`,
  // which is not const. Files from before damage existed have no flag and no damage.
  s.history.damage = r.has("history.damage") && r.i64("history.damage") != 0;
  for (const auto& [name, column] : s.history.columns())
    *const_cast<std::vector<double>*>(column) = r.f64s("history." + name);
  s.history.modes = unflatten(r, "history.modes");
  s.history.modes_z_mean = unflatten(r, "history.modes_z_mean");

  const std::string prefix = "state.";
  for (const auto& name : r.names(prefix)) {
    StateArray a;
    a.name = name.substr(prefix.size());
    a.single = r.type(name) == kF32;
    if (a.single)
      a.f32 = r.f32s(name);
    else
      a.f64 = r.f64s(name);
    s.arrays.push_back(std::move(a));
  }
  return c;
}

}  // namespace softshock
