#include "solver/mesh_cache.hpp"

#include <fcntl.h>
#include <google/protobuf/io/coded_stream.h>
#include <google/protobuf/io/zero_copy_stream_impl_lite.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <random>
#include <stdexcept>
#include <thread>
#include <vector>

#include "solver/gmsh_mesher.hpp"

namespace softshock {
namespace {

namespace fs = std::filesystem;

constexpr char kMagic[8] = {'S', 'S', 'M', 'E', 'S', 'H', '\0', '\1'};
// Bump kFormatVersion when the entry layout changes, kMesherRevision when the meshes themselves
// would change for the same geometry (gmsh_mesher.cpp's algorithm, ring_mesher.cpp,
// sort_for_locality) -- and then run_summary.hpp's kSolverRevision too: the results change.
constexpr std::uint32_t kFormatVersion = 2;  // 2: z, tetrahedra and boundary faces (3-D)
constexpr int kMesherRevision = 2;           // 2: ring_mesher.cpp's hexagonal centre
constexpr const char* kSuffix = ".mesh";
constexpr const char* kTmpMarker = ".tmp.";
constexpr int kLockStripes = 64;  // lock files, never removed: a bounded set
constexpr auto kStaleTmpAge = std::chrono::hours(1);

// FNV-1a over 8-byte words with a final avalanche: fast enough for checksums of a few MB
// (~0.3 ms for the 16.5k-element disk). Not cryptographic: keys are verified against the
// stored material, so a collision costs a miss, never a wrong mesh.
std::uint64_t hash64(std::string_view bytes, std::uint64_t seed) {
  std::uint64_t h = 0xcbf29ce484222325ULL ^ seed;
  std::size_t i = 0;
  for (; i + 8 <= bytes.size(); i += 8) {
    std::uint64_t w;
    std::memcpy(&w, bytes.data() + i, 8);
    h = (h ^ w) * 0x100000001b3ULL;
    h ^= h >> 29;
  }
  for (; i < bytes.size(); ++i) h = (h ^ static_cast<unsigned char>(bytes[i])) * 0x100000001b3ULL;
  h ^= h >> 33;
  h *= 0xff51afd7ed558ccdULL;
  h ^= h >> 33;
  h *= 0xc4ceb9fe1a85ec53ULL;
  h ^= h >> 33;
  return h;
}

std::string hex64(std::uint64_t v) {
  static const char* digits = "0123456789abcdef";
  std::string s(16, '0');
  for (int i = 15; i >= 0; --i, v >>= 4) s[static_cast<std::size_t>(i)] = digits[v & 0xf];
  return s;
}

struct Header {
  char magic[8];
  std::uint32_t format_version;
  std::uint32_t material_bytes;
  std::uint64_t nodes, triangles, boundary_edges, boundary_nodes;
  std::uint64_t z_nodes, tetrahedra, boundary_faces;  // 3-D; 0 in a 2-D entry
};

// Empty arrays (a 2-D mesh's 3-D ones, and the reverse) may have a null data(): skipped, as
// memcpy from or to null is undefined even for zero bytes.
template <typename T>
void append(std::string& out, const std::vector<T>& v) {
  if (!v.empty()) out.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
}

std::string serialize(const std::string& material, const Mesh& mesh) {
  Header h{};
  std::memcpy(h.magic, kMagic, sizeof kMagic);
  h.format_version = kFormatVersion;
  h.material_bytes = static_cast<std::uint32_t>(material.size());
  h.nodes = mesh.x.size();
  h.triangles = mesh.triangles.size();
  h.boundary_edges = mesh.boundary_edges.size();
  h.boundary_nodes = mesh.boundary_nodes.size();
  h.z_nodes = mesh.z.size();
  h.tetrahedra = mesh.tetrahedra.size();
  h.boundary_faces = mesh.boundary_faces.size();
  std::string out(reinterpret_cast<const char*>(&h), sizeof h);
  out += material;
  append(out, mesh.x);
  append(out, mesh.y);
  append(out, mesh.triangles);
  append(out, mesh.boundary_edges);
  append(out, mesh.boundary_nodes);
  append(out, mesh.z);
  append(out, mesh.tetrahedra);
  append(out, mesh.boundary_faces);
  const std::uint64_t sum = hash64(out, 0);
  out.append(reinterpret_cast<const char*>(&sum), sizeof sum);
  return out;
}

template <typename T>
std::uint64_t bytes_of(const std::vector<T>& v) {
  return v.size() * sizeof(T);
}

// serialize(material, mesh).size() without building it.
std::uint64_t entry_bytes(const Mesh& mesh, const std::string& material) {
  return sizeof(Header) + material.size() + bytes_of(mesh.x) + bytes_of(mesh.y) +
         bytes_of(mesh.triangles) + bytes_of(mesh.boundary_edges) + bytes_of(mesh.boundary_nodes) +
         bytes_of(mesh.z) + bytes_of(mesh.tetrahedra) + bytes_of(mesh.boundary_faces) +
         sizeof(std::uint64_t);
}

template <typename T>
bool take(std::string_view& in, std::vector<T>& v, std::uint64_t count) {
  if (count > in.size() / sizeof(T)) return false;
  v.resize(count);
  if (count == 0) return true;  // data() may be null; see append()
  std::memcpy(v.data(), in.data(), count * sizeof(T));
  in.remove_prefix(count * sizeof(T));
  return true;
}

// nullopt for anything but a whole, consistent entry of `material`.
std::optional<Mesh> deserialize(std::string_view bytes, const std::string& material) {
  if (bytes.size() < sizeof(Header) + sizeof(std::uint64_t)) return std::nullopt;
  std::uint64_t sum;
  std::memcpy(&sum, bytes.data() + bytes.size() - sizeof sum, sizeof sum);
  std::string_view in = bytes.substr(0, bytes.size() - sizeof sum);
  if (hash64(in, 0) != sum) return std::nullopt;
  Header h;
  std::memcpy(&h, in.data(), sizeof h);
  in.remove_prefix(sizeof h);
  if (std::memcmp(h.magic, kMagic, sizeof kMagic) != 0 || h.format_version != kFormatVersion ||
      h.material_bytes != material.size() || in.substr(0, material.size()) != material) {
    return std::nullopt;
  }
  in.remove_prefix(material.size());
  Mesh m;
  if (!take(in, m.x, h.nodes) || !take(in, m.y, h.nodes) || !take(in, m.triangles, h.triangles) ||
      !take(in, m.boundary_edges, h.boundary_edges) ||
      !take(in, m.boundary_nodes, h.boundary_nodes) || !take(in, m.z, h.z_nodes) ||
      !take(in, m.tetrahedra, h.tetrahedra) || !take(in, m.boundary_faces, h.boundary_faces) ||
      !in.empty()) {
    return std::nullopt;
  }
  // A mesh is 2-D (triangles, no z, no 3-D arrays) or 3-D (tetrahedra with z for every node,
  // no 2-D arrays); anything else is not one the solver can take.
  const bool two_d =
      !m.triangles.empty() && m.z.empty() && m.tetrahedra.empty() && m.boundary_faces.empty();
  const bool three_d = !m.tetrahedra.empty() && m.z.size() == h.nodes && m.triangles.empty() &&
                       m.boundary_edges.empty() && m.boundary_nodes.empty();
  if (!two_d && !three_d) return std::nullopt;
  // The solver indexes with these unchecked: a bad index must not get through.
  const auto n = static_cast<std::int64_t>(h.nodes);
  auto in_range = [n](std::int32_t i) { return i >= 0 && i < n; };
  for (const auto& t : m.triangles)
    if (!std::all_of(t.begin(), t.end(), in_range)) return std::nullopt;
  for (const auto& e : m.boundary_edges)
    if (!std::all_of(e.begin(), e.end(), in_range)) return std::nullopt;
  if (!std::all_of(m.boundary_nodes.begin(), m.boundary_nodes.end(), in_range)) return std::nullopt;
  for (const auto& t : m.tetrahedra)
    if (!std::all_of(t.begin(), t.end(), in_range)) return std::nullopt;
  for (const auto& f : m.boundary_faces)
    if (!std::all_of(f.begin(), f.end(), in_range)) return std::nullopt;
  return m;
}

std::string read_file(const std::string& path, bool* exists) {
  *exists = false;
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return {};
  *exists = true;
  struct stat st {};
  std::string data;
  if (::fstat(fd, &st) == 0 && st.st_size > 0) {
    data.resize(static_cast<std::size_t>(st.st_size));
    std::size_t done = 0;
    while (done < data.size()) {
      const ssize_t n = ::read(fd, data.data() + done, data.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) break;
      done += static_cast<std::size_t>(n);
    }
    data.resize(done);
    // Last use for the LRU order. Best effort: a read-only cache still serves.
    (void)::futimens(fd, nullptr);
  }
  ::close(fd);
  return data;
}

// An exclusive flock on one of kLockStripes files, held for the object's lifetime.
class StripeLock {
 public:
  StripeLock(const fs::path& dir, const std::string& key) {
    const std::uint64_t stripe = hash64(key, 1) % kLockStripes;
    const fs::path locks = dir / "locks";
    std::error_code ec;
    fs::create_directories(locks, ec);
    const std::string path = (locks / (std::to_string(stripe) + ".lock")).string();
    fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd_ < 0) return;  // no lock: concurrent builders then both build (still correct)
    while (::flock(fd_, LOCK_EX) != 0 && errno == EINTR) {
    }
  }
  ~StripeLock() {
    if (fd_ >= 0) ::close(fd_);  // releases the lock
  }
  StripeLock(const StripeLock&) = delete;
  StripeLock& operator=(const StripeLock&) = delete;

 private:
  int fd_ = -1;
};

bool is_entry(const std::string& name) {
  return name.size() > std::strlen(kSuffix) &&
         name.compare(name.size() - std::strlen(kSuffix), std::string::npos, kSuffix) == 0;
}

}  // namespace

const char* to_string(MeshCacheOutcome outcome) {
  switch (outcome) {
    case MeshCacheOutcome::kHit:
      return "hit";
    case MeshCacheOutcome::kMiss:
      return "miss";
    case MeshCacheOutcome::kReplaced:
      return "replaced";
    case MeshCacheOutcome::kNotUsed:
      break;
  }
  return "not-used";
}

MeshCache::MeshCache(std::string dir, std::uint64_t max_bytes)
    : dir_(std::move(dir)), max_bytes_(max_bytes) {
  std::error_code ec;
  fs::create_directories(dir_, ec);
  if (ec || !fs::is_directory(dir_, ec)) {
    throw std::runtime_error("mesh cache: cannot create " + dir_ + ": " + ec.message());
  }
}

std::string MeshCache::entry_path(const std::string& key) const {
  return (fs::path(dir_) / (key + kSuffix)).string();
}

std::optional<Mesh> MeshCache::load(const std::string& key, const std::string& material,
                                    bool* unusable) const {
  return read_mesh_entry(entry_path(key), material, unusable);
}

void MeshCache::store(const std::string& key, const std::string& material, const Mesh& mesh) const {
  if (entry_bytes(mesh, material) > max_bytes_) return;  // would evict everything, itself included
  write_mesh_entry(entry_path(key), material, mesh);
  evict();
}

void MeshCache::evict() const {
  struct Entry {
    fs::file_time_type used;
    std::uint64_t bytes;
    fs::path path;
  };
  std::vector<Entry> entries;
  std::uint64_t total = 0;
  const auto now = fs::file_time_type::clock::now();
  std::error_code ec;
  for (const auto& item : fs::directory_iterator(dir_, ec)) {
    std::error_code item_ec;
    const std::string name = item.path().filename().string();
    const auto used = item.last_write_time(item_ec);
    if (item_ec) continue;  // removed meanwhile
    if (name.find(kTmpMarker) != std::string::npos) {
      // A writer killed before its rename; live writers take milliseconds.
      if (now - used > kStaleTmpAge) fs::remove(item.path(), item_ec);
      continue;
    }
    if (!is_entry(name)) continue;
    const std::uint64_t bytes = item.file_size(item_ec);
    if (item_ec) continue;
    entries.push_back({used, bytes, item.path()});
    total += bytes;
  }
  if (total <= max_bytes_) return;
  std::sort(entries.begin(), entries.end(),
            [](const Entry& a, const Entry& b) { return a.used < b.used; });
  for (const Entry& e : entries) {
    if (total <= max_bytes_) break;
    std::error_code remove_ec;
    // A reader that has it open keeps reading the unlinked file.
    if (fs::remove(e.path, remove_ec)) total -= e.bytes;
  }
}

Mesh MeshCache::get_or_build(const std::string& key, const std::string& material,
                             const std::function<Mesh()>& build, MeshCacheOutcome* outcome,
                             std::string* warning) const {
  auto set = [&](MeshCacheOutcome o) {
    if (outcome) *outcome = o;
  };
  if (auto mesh = load(key, material)) {
    set(MeshCacheOutcome::kHit);
    return *mesh;
  }
  // Another worker may be building this key: wait for it, then look again.
  StripeLock lock(dir_, key);
  bool unusable = false;
  if (auto mesh = load(key, material, &unusable)) {
    set(MeshCacheOutcome::kHit);
    return *mesh;
  }
  Mesh mesh = build();
  set(unusable ? MeshCacheOutcome::kReplaced : MeshCacheOutcome::kMiss);
  try {
    store(key, material, mesh);
  } catch (const std::exception& e) {
    if (warning) *warning = e.what();
  }
  return mesh;
}

std::optional<Mesh> read_mesh_entry(const std::string& path, const std::string& material,
                                    bool* unusable) {
  if (unusable) *unusable = false;
  bool exists = false;
  const std::string bytes = read_file(path, &exists);
  if (!exists) return std::nullopt;
  auto mesh = deserialize(bytes, material);
  if (!mesh && unusable) *unusable = true;
  return mesh;
}

void write_mesh_entry(const std::string& path, const std::string& material, const Mesh& mesh) {
  const std::string bytes = serialize(material, mesh);
  // Unique among the writers of a shared folder: pids repeat across the nodes of a cluster.
  static const std::string writer_id = [] {
    std::random_device random;
    return std::to_string(::getpid()) + "." + hex64((std::uint64_t{random()} << 32) | random());
  }();
  static std::atomic<unsigned> counter{0};
  const std::string tmp =
      path + kTmpMarker + writer_id + "." + std::to_string(counter.fetch_add(1));
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
  if (fd < 0) throw std::runtime_error("mesh cache: cannot create " + tmp + ": " + strerror(errno));
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const int saved = errno;
      ::close(fd);
      ::unlink(tmp.c_str());
      throw std::runtime_error("mesh cache: cannot write " + tmp + ": " + strerror(saved));
    }
    done += static_cast<std::size_t>(n);
  }
  // No fsync: a cache entry is not precious, and one torn by a power loss fails its checksum.
  if (::close(fd) != 0 || std::rename(tmp.c_str(), path.c_str()) != 0) {
    const int saved = errno;
    ::unlink(tmp.c_str());
    throw std::runtime_error("mesh cache: cannot store " + path + ": " + strerror(saved));
  }
}

namespace {

// Every field, in a fixed order: equal messages give equal bytes.
std::optional<std::string> deterministic_bytes(const v1::Geometry& geometry) {
  std::string serialized;
  {
    google::protobuf::io::StringOutputStream stream(&serialized);
    google::protobuf::io::CodedOutputStream coded(&stream);
    coded.SetSerializationDeterministic(true);  // map order etc. fixed
    if (!geometry.SerializeToCodedStream(&coded)) return std::nullopt;
  }  // the streams' destructors trim `serialized` to what was written
  return serialized;
}

}  // namespace

std::optional<std::string> mesh_key_material(const v1::Geometry& geometry) {
  // A mesh file is read, not meshed, and its content may change under the same name.
  if (geometry.shape_case() != v1::Geometry::kDisk &&
      geometry.shape_case() != v1::Geometry::kRoundedSquare &&
      geometry.shape_case() != v1::Geometry::kCylinder) {
    return std::nullopt;
  }
  // A cylinder's faces are boundary conditions, not geometry: one mesh serves all three.
  v1::Geometry keyed = geometry;
  if (keyed.has_cylinder()) keyed.mutable_cylinder()->clear_faces();
  const auto serialized = deterministic_bytes(keyed);
  if (!serialized) return std::nullopt;
  return "softshock-mesh format=" + std::to_string(kFormatVersion) +
         " mesher=" + std::to_string(kMesherRevision) + " gmsh=" + gmsh_version() + "\n" +
         *serialized;
}

std::string mesh_entry_material(const v1::Geometry& geometry) {
  if (auto material = mesh_key_material(geometry)) return *material;
  return "softshock-mesh uncached\n" + deterministic_bytes(geometry).value_or("");
}

std::string mesh_cache_key(const std::string& material) {
  return hex64(hash64(material, 0x9e3779b97f4a7c15ULL)) +
         hex64(hash64(material, 0x2545f4914f6cdd1dULL));
}

std::string default_mesh_cache_dir() {
  if (const char* v = std::getenv("SOFTSHOCK_MESH_CACHE"); v != nullptr && *v != '\0') {
    return std::string(v) == "off" ? std::string() : std::string(v);
  }
  if (const char* v = std::getenv("XDG_CACHE_HOME"); v != nullptr && *v == '/') {
    return (fs::path(v) / "softshock" / "meshes").string();
  }
  if (const char* v = std::getenv("HOME"); v != nullptr && *v == '/') {
    return (fs::path(v) / ".cache" / "softshock" / "meshes").string();
  }
  return {};
}

std::uint64_t default_mesh_cache_bytes() {
  const char* v = std::getenv("SOFTSHOCK_MESH_CACHE_BYTES");
  if (v == nullptr || *v == '\0') return std::uint64_t{512} << 20;
  std::uint64_t bytes = 0;
  const char* end = v + std::strlen(v);
  const auto [ptr, ec] = std::from_chars(v, end, bytes);
  if (ec != std::errc() || ptr != end) {
    throw std::invalid_argument("SOFTSHOCK_MESH_CACHE_BYTES: expects a number of bytes, got '" +
                                std::string(v) + "'");
  }
  return bytes;
}

}  // namespace softshock
