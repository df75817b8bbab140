// SimulationService's DownloadResult: a finished job's result.h5, result.xdmf, spec and summary
// streamed to the client in parts it can resume (docs/api.md, "DownloadResult"). One call sends
// at most kMaxBytesPerCall from the offset the client asks for, in chunks of kChunkBytes; the
// first message names the file, its size and the SHA-256 of the whole file, which the client
// checks once it holds every byte. The result files are read with pread from one descriptor
// (a file deleted meanwhile stays readable to the end of the call); their digest is computed
// once per file (FileDigests). The spec and the summary are produced from the catalogue,
// byte for byte the same on every call.
#include <fcntl.h>
#include <google/protobuf/util/json_util.h>
#include <grpcpp/grpcpp.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <string>

#include "server/store/spec_hash.hpp"
#include "server/transport/resource_name.hpp"
#include "server/transport/rpc_guard.hpp"
#include "server/transport/rpc_support.hpp"
#include "server/transport/simulation_service.hpp"

namespace softshock::server {

namespace fs = std::filesystem;
using namespace rpc;
using grpc::Status;
using grpc::StatusCode;

namespace {

constexpr int64_t kChunkBytes = int64_t{512} << 10;      // per DownloadChunk
constexpr int64_t kMaxBytesPerCall = int64_t{64} << 20;  // per call: the client loops

// A descriptor closed on every path.
class Fd {
 public:
  explicit Fd(int fd) : fd_(fd) {}
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const { return fd_; }

 private:
  int fd_;
};

const char* file_name(v1::ResultFileKind kind) {
  switch (kind) {
    case v1::RESULT_H5:
      return "result.h5";
    case v1::RESULT_XDMF:
      return "result.xdmf";
    case v1::SPEC:
      return "spec.json";
    case v1::SUMMARY:
      return "summary.json";
    default:
      return "";
  }
}

// The normalised spec as a spec file: protobuf JSON, every field written, one trailing newline.
std::string spec_file_text(const std::string& stored_json) {
  google::protobuf::util::JsonPrintOptions options;
  options.add_whitespace = true;
  options.always_print_primitive_fields = true;
  std::string out;
  const auto status =
      google::protobuf::util::MessageToJsonString(parse_stored_spec(stored_json), &out, options);
  if (!status.ok()) throw std::runtime_error("cannot print the spec: " + status.ToString());
  if (out.empty() || out.back() != '\n') out += '\n';
  return out;
}

}  // namespace

Status SimulationService::DownloadResult(grpc::ServerContext* ctx,
                                         const v1::DownloadResultRequest* req,
                                         grpc::ServerWriter<v1::DownloadChunk>* writer) {
  return guarded(auth_, ctx, "DownloadResult", [&]() -> Status {
    StreamSlot slot(*this);
    if (!slot.acquired()) {
      return {StatusCode::RESOURCE_EXHAUSTED,
              "too many concurrent streams (" + std::to_string(config_.max_streams) + ")"};
    }
    return download(ctx, *req, writer);
  });
}

Status SimulationService::download(grpc::ServerContext* ctx, const v1::DownloadResultRequest& req,
                                   grpc::ServerWriter<v1::DownloadChunk>* writer) {
  std::string id;
  if (Status st = requested_id(req, "jobs/", &id); !st.ok()) return st;
  const std::string name = file_name(req.file());
  if (name.empty()) {
    return invalid("file", "must be RESULT_H5, RESULT_XDMF, SPEC or SUMMARY");
  }
  if (req.offset() < 0) return invalid("offset", "must not be negative");
  if (req.max_bytes() < 0) return invalid("max_bytes", "must not be negative (0 = 64 MiB)");
  const int64_t budget =
      req.max_bytes() == 0 ? kMaxBytesPerCall : std::min(req.max_bytes(), kMaxBytesPerCall);

  auto record = catalogue_.get(id);
  if (!record) return not_found(id);
  if (!is_terminal(record->state)) {
    return {StatusCode::FAILED_PRECONDITION, "job " + id + " is " + to_string(record->state) +
                                                 "; its files can be downloaded once it finished"};
  }

  // The bytes: a file of the job's folder, or text made from the catalogue.
  std::string text;
  std::unique_ptr<Fd> fd;
  v1::ResultFileInfo info;
  info.set_file_name(name);
  info.set_complete(true);
  if (req.file() == v1::RESULT_H5 || req.file() == v1::RESULT_XDMF) {
    const std::string h5 = record->result_path;
    const std::string path =
        req.file() == v1::RESULT_H5 ? h5 : (fs::path(h5).parent_path() / "result.xdmf").string();
    if (h5.empty()) {
      return {StatusCode::FAILED_PRECONDITION,
              "job " + id + " is " + to_string(record->state) + " and has no result file"};
    }
    fd = std::make_unique<Fd>(::open(path.c_str(), O_RDONLY | O_CLOEXEC));
    if (fd->get() < 0) {
      return {StatusCode::FAILED_PRECONDITION, "job " + id + " is " + to_string(record->state) +
                                                   " and has no " + name + " (" +
                                                   std::strerror(errno) + ")"};
    }
    auto digest = digests_.digest(fd->get(), [ctx] { return ctx->IsCancelled(); });
    if (!digest) return {StatusCode::CANCELLED, "download cancelled by the client"};
    struct stat st {};
    if (::fstat(fd->get(), &st) != 0) throw std::runtime_error(std::strerror(errno));
    info.set_size(static_cast<int64_t>(st.st_size));
    info.set_sha256(*digest);
    info.set_complete(record->state == JobState::kSucceeded);
  } else if (req.file() == v1::SPEC) {
    text = spec_file_text(record->spec_json);
  } else {
    auto stored = catalogue_.summary(id);
    if (!stored) {
      return {StatusCode::FAILED_PRECONDITION,
              "job " + id + " is " + to_string(record->state) + " and has no summary"};
    }
    text = summary_to_json(stored->summary) + "\n";
  }
  if (!fd) {
    info.set_size(static_cast<int64_t>(text.size()));
    info.set_sha256(sha256_hex(text));
  }
  if (req.offset() > info.size()) {
    return invalid("offset", std::to_string(req.offset()) + " is beyond the end of " + name + " (" +
                                 std::to_string(info.size()) + " bytes)");
  }

  v1::DownloadChunk first;
  *first.mutable_info() = info;
  first.set_offset(req.offset());
  if (!writer->Write(first)) return {StatusCode::CANCELLED, "client went away"};
  const int64_t end = std::min(info.size(), req.offset() + budget);
  std::string block;
  for (int64_t at = req.offset(); at < end;) {
    if (ctx->IsCancelled()) return {StatusCode::CANCELLED, "download cancelled by the client"};
    const int64_t want = std::min(kChunkBytes, end - at);
    v1::DownloadChunk chunk;
    chunk.set_offset(at);
    if (fd) {
      block.resize(static_cast<std::size_t>(want));
      const ssize_t n = ::pread(fd->get(), block.data(), block.size(), at);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) throw std::runtime_error(name + ": " + std::strerror(errno));
      if (n == 0) return {StatusCode::INTERNAL, name + " ended before its size"};
      chunk.set_data(block.data(), static_cast<std::size_t>(n));
    } else {
      chunk.set_data(text.substr(static_cast<std::size_t>(at), static_cast<std::size_t>(want)));
    }
    at += static_cast<int64_t>(chunk.data().size());
    if (!writer->Write(chunk)) return {StatusCode::CANCELLED, "client went away"};
  }
  return Status::OK;
}

}  // namespace softshock::server
