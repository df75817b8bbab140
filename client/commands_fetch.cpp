// softshock fetch: a finished job's result.h5, result.xdmf, spec.json and summary.json into a
// folder on this machine (DownloadResult, docs/api.md), so ParaView, h5py or softshock-solve can
// open them where the user sits. Each file arrives as NAME.part and becomes NAME (a rename) only
// once its SHA-256 equals the one the daemon sends; a later fetch continues a NAME.part from its
// size, and leaves a NAME that already has the daemon's digest alone. The daemon sends at most
// 64 MiB per call: the loop asks again from the size it holds, so a call cut short (deadline, a
// restarting daemon) costs nothing it had already received.
#include <fcntl.h>
#include <google/protobuf/struct.pb.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

#include "client/commands.hpp"
#include "client/format.hpp"
#include "client/sha256.hpp"

namespace softshock::cli {

namespace {

namespace fs = std::filesystem;

struct Kind {
  v1::ResultFileKind kind;
  const char* option;  // --file value
};
constexpr Kind kKinds[] = {
    {v1::RESULT_H5, "h5"}, {v1::RESULT_XDMF, "xdmf"}, {v1::SPEC, "spec"}, {v1::SUMMARY, "summary"}};

// What became of one file.
struct Fetched {
  std::string name;  // result.h5, ...
  std::string path;  // where it lies now
  int64_t size = 0;
  std::string sha256;
  int64_t resumed_from = 0;  // bytes of a NAME.part a previous fetch left
  std::string outcome;       // "downloaded", "up to date", "skipped: why"
};

// A file descriptor closed on every path.
class OutFile {
 public:
  explicit OutFile(const fs::path& path)
      : fd_(::open(path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644)) {
    if (fd_ < 0) throw CliError(kExitFailure, path.string() + ": " + std::strerror(errno));
  }
  ~OutFile() {
    if (fd_ >= 0) ::close(fd_);
  }
  OutFile(const OutFile&) = delete;
  OutFile& operator=(const OutFile&) = delete;
  void write(const std::string& bytes, const fs::path& path) {
    for (std::size_t done = 0; done < bytes.size();) {
      const ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0) throw CliError(kExitFailure, path.string() + ": " + std::strerror(errno));
      done += static_cast<std::size_t>(n);
    }
  }
  void sync(const fs::path& path) {
    if (::fsync(fd_) != 0)
      throw CliError(kExitFailure, path.string() + ": " + std::strerror(errno));
  }

 private:
  int fd_;
};

int64_t size_or_zero(const fs::path& path) {
  std::error_code ec;
  const auto size = fs::file_size(path, ec);
  return ec ? 0 : static_cast<int64_t>(size);
}

// `Format="HDF">  /some/folder/result.h5:/path` becomes `Format="HDF">  result.h5:/path`.
// (By hand, not std::regex: GCC 12 warns maybe-uninitialized inside it in the sanitizer build.)
std::string relative_h5_references(const std::string& text) {
  static const std::string kTag = "Format=\"HDF\">";
  std::string out;
  std::size_t from = 0;
  for (std::size_t at; (at = text.find(kTag, from)) != std::string::npos;) {
    std::size_t p = at + kTag.size();
    while (p < text.size() && std::isspace(static_cast<unsigned char>(text[p]))) ++p;
    out.append(text, from, p - from);
    from = p;
    const std::size_t colon = text.find_first_of("<:", p);
    if (colon == std::string::npos || text[colon] != ':') continue;
    const std::string reference = text.substr(p, colon - p);
    const auto slash = reference.rfind('/');
    if (slash == std::string::npos) continue;
    const std::string name = reference.substr(slash + 1);
    if (name.size() > 3 && name.ends_with(".h5")) {
      out += name;
      from = colon;
    }
  }
  out.append(text, from);
  return out;
}

// The XDMF's HDF5 references must name result.h5 beside it (ParaView resolves them against the
// XDMF's folder). The daemon writes them so; one written with a folder in front is rewritten.
bool make_xdmf_relative(const fs::path& xdmf) {
  std::ifstream in(xdmf, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  const std::string before = text.str();
  const std::string after = relative_h5_references(before);
  if (after == before) return false;
  const fs::path tmp = xdmf.string() + ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out << after;
    if (!out.flush()) throw CliError(kExitFailure, tmp.string() + ": write failed");
  }
  fs::rename(tmp, xdmf);
  return true;
}

class Fetcher {
 public:
  Fetcher(Connection& conn, std::string id, fs::path dir)
      : conn_(conn), id_(std::move(id)), dir_(std::move(dir)), tty_(isatty(STDERR_FILENO) != 0) {}

  Fetched fetch(v1::ResultFileKind kind);

 private:
  struct Call {
    v1::ResultFileInfo info;
    bool got_info = false;
    int64_t received = 0;
    grpc::Status status;
  };
  // One DownloadResult call from `offset`, appending what arrives to `out` (when given).
  Call call(v1::ResultFileKind kind, int64_t offset, int64_t max_bytes, OutFile* out,
            const fs::path& part);
  void progress(const std::string& name, int64_t have, int64_t size);

  Connection& conn_;
  std::string id_;
  fs::path dir_;
  bool tty_;
};

Fetcher::Call Fetcher::call(v1::ResultFileKind kind, int64_t offset, int64_t max_bytes,
                            OutFile* out, const fs::path& part) {
  v1::DownloadResultRequest request;
  request.set_name("jobs/" + id_);
  request.set_file(kind);
  request.set_offset(offset);
  request.set_max_bytes(max_bytes);
  Call result;
  auto ctx = conn_.context();
  auto reader = conn_.service().DownloadResult(ctx.get(), request);
  v1::DownloadChunk chunk;
  while (reader->Read(&chunk)) {
    if (chunk.has_info()) {
      result.info = chunk.info();
      result.got_info = true;
    }
    if (chunk.data().empty()) continue;
    if (!result.got_info || out == nullptr ||
        chunk.offset() != offset + result.received) {  // nothing arrives out of order
      ctx->TryCancel();
      break;
    }
    out->write(chunk.data(), part);
    result.received += static_cast<int64_t>(chunk.data().size());
    progress(result.info.file_name(), offset + result.received, result.info.size());
  }
  result.status = reader->Finish();
  return result;
}

void Fetcher::progress(const std::string& name, int64_t have, int64_t size) {
  if (!tty_ || size < (int64_t{4} << 20)) return;
  std::fprintf(stderr, "\r\033[K%s  %5.1f%%  %.1f of %.1f MiB", name.c_str(),
               100.0 * static_cast<double>(have) / static_cast<double>(size),
               static_cast<double>(have) / 1048576.0, static_cast<double>(size) / 1048576.0);
  if (have >= size) std::fprintf(stderr, "\r\033[K");
}

Fetched Fetcher::fetch(v1::ResultFileKind kind) {
  Fetched f;
  // The daemon names the file; ask for its header (and one byte) first.
  Call probe = call(kind, 0, 1, nullptr, {});
  if (!probe.got_info) {
    if (probe.status.error_code() == grpc::StatusCode::FAILED_PRECONDITION) {
      f.name = v1::ResultFileKind_Name(kind);
      f.outcome = "skipped: " + probe.status.error_message();
      return f;
    }
    throw status_error(probe.status.ok() ? grpc::Status(grpc::StatusCode::INTERNAL,
                                                        "the daemon sent no file header")
                                         : probe.status,
                       conn_.target());
  }
  v1::ResultFileInfo expected = probe.info;
  f.name = expected.file_name();
  if (f.name.empty() || f.name.find('/') != std::string::npos || f.name[0] == '.') {
    throw CliError(kExitFailure, "the daemon named a file '" + f.name + "'");
  }
  const fs::path final_path = dir_ / f.name;
  const fs::path part = dir_ / (f.name + ".part");
  f.path = final_path.string();
  f.size = expected.size();
  f.sha256 = expected.sha256();
  if (fs::exists(final_path) && size_or_zero(final_path) == expected.size() &&
      sha256_of_file(final_path.string()) == expected.sha256()) {
    std::error_code ec;
    fs::remove(part, ec);
    f.outcome = "up to date";
    return f;
  }
  int64_t have = size_or_zero(part);
  if (have > expected.size()) {  // a partial file of something else: start again
    fs::remove(part);
    have = 0;
  }
  f.resumed_from = have;
  bool started_over = false;
  int stalls = 0;
  for (;;) {
    while (have < expected.size()) {
      OutFile out(part);
      Call c = call(kind, have, 0, &out, part);
      if (c.got_info && c.info.sha256() != expected.sha256()) {
        // The file changed on the daemon since the part began (a job deleted and its id
        // reused is impossible; a result rewritten is not): start it again.
        if (started_over) throw CliError(kExitFailure, f.name + " keeps changing on the daemon");
        started_over = true;
        fs::resize_file(part, 0);
        expected = c.info;
        have = 0;
        continue;
      }
      have += c.received;
      if (c.status.ok()) continue;
      const auto code = c.status.error_code();
      const bool transient = code == grpc::StatusCode::UNAVAILABLE ||
                             code == grpc::StatusCode::DEADLINE_EXCEEDED ||
                             code == grpc::StatusCode::RESOURCE_EXHAUSTED;
      if (!transient) throw status_error(c.status, conn_.target());
      // A call cut short keeps what it brought; only calls that bring nothing count.
      stalls = c.received > 0 ? 0 : stalls + 1;
      if (stalls >= 4) throw status_error(c.status, conn_.target());
      std::this_thread::sleep_for(std::chrono::milliseconds(250 * stalls));
    }
    if (sha256_of_file(part.string()) == expected.sha256()) break;
    if (f.resumed_from > 0 && !started_over) {
      // The part a previous fetch left did not belong to this file after all: once more, whole.
      started_over = true;
      fs::resize_file(part, 0);
      have = 0;
      continue;
    }
    throw CliError(kExitFailure, f.name +
                                     ": the downloaded bytes' SHA-256 differs from the "
                                     "daemon's " +
                                     expected.sha256() + " (" + part.string() +
                                     " kept; fetch again)");
  }
  OutFile(part).sync(part);
  fs::rename(part, final_path);
  f.size = expected.size();
  f.sha256 = expected.sha256();
  f.outcome = started_over && f.resumed_from > 0 ? "downloaded (the partial file did not match)"
                                                 : "downloaded";
  if (kind == v1::RESULT_XDMF && make_xdmf_relative(final_path)) {
    f.outcome += "; HDF5 references made relative";
  }
  return f;
}

std::string fmt_bytes(int64_t bytes) {
  const double b = static_cast<double>(bytes);
  if (bytes < 1024) return std::to_string(bytes) + " B";
  if (bytes < (int64_t{1} << 20)) return fmt_num(b / 1024.0, 3) + " KiB";
  if (bytes < (int64_t{1} << 30)) return fmt_num(b / 1048576.0, 3) + " MiB";
  return fmt_num(b / 1073741824.0, 3) + " GiB";
}

}  // namespace

int cmd_fetch(const GlobalOptions& g, const ParsedArgs& a) {
  const std::string& id = a.positional.at(0);
  std::vector<v1::ResultFileKind> kinds;
  for (const auto& wanted : a.all("file")) {
    bool known = false;
    for (const auto& k : kKinds) {
      if (wanted == k.option) {
        kinds.push_back(k.kind);
        known = true;
      }
    }
    if (!known) usage_error("--file: '" + wanted + "' is not one of h5, xdmf, spec, summary");
  }
  if (kinds.empty()) {
    for (const auto& k : kKinds) kinds.push_back(k.kind);
  }
  Connection conn(g);
  v1::GetJobRequest get;
  get.set_name(id);
  v1::Job job;
  conn.unary([&](grpc::ClientContext& ctx) { return conn.service().GetJob(&ctx, get, &job); });
  if (!is_terminal(job.state())) {
    throw CliError(kExitFailure, "job " + job.id() + " is " + state_name(job.state()) +
                                     ": its files can be fetched once it finished (softshock "
                                     "watch " +
                                     job.id() + ")");
  }
  const fs::path dir = a.positional.size() > 1 ? fs::path(a.positional[1]) : fs::path(job.id());
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) throw CliError(kExitFailure, dir.string() + ": " + ec.message());

  Fetcher fetcher(conn, job.id(), dir);
  std::vector<Fetched> done;
  for (auto kind : kinds) done.push_back(fetcher.fetch(kind));
  bool any = false;
  for (const auto& f : done) any = any || f.outcome.rfind("skipped", 0) != 0;

  if (g.json) {
    google::protobuf::ListValue files;
    for (const auto& f : done) {
      auto& fields = *files.add_values()->mutable_struct_value()->mutable_fields();
      fields["file"].set_string_value(f.name);
      fields["path"].set_string_value(f.path);
      fields["size"].set_number_value(static_cast<double>(f.size));
      fields["sha256"].set_string_value(f.sha256);
      fields["resumed_from"].set_number_value(static_cast<double>(f.resumed_from));
      fields["outcome"].set_string_value(f.outcome);
    }
    std::printf("%s\n", to_json(files).c_str());
  } else {
    std::printf("job %s (%s) into %s/\n", job.id().c_str(), state_name(job.state()).c_str(),
                dir.string().c_str());
    std::vector<std::vector<std::string>> rows;
    for (const auto& f : done) {
      std::string outcome = f.outcome;
      if (f.resumed_from > 0 && outcome == "downloaded") {
        outcome += " (resumed at " + fmt_bytes(f.resumed_from) + ")";
      }
      rows.push_back({f.name, f.path.empty() ? "-" : fmt_bytes(f.size),
                      f.sha256.empty() ? "-" : f.sha256.substr(0, 16), outcome});
    }
    print_table(stdout, {"FILE", "SIZE", "SHA256", "OUTCOME"}, rows);
    for (const auto& f : done) {
      if (f.name == "result.xdmf" && f.outcome.rfind("skipped", 0) != 0) {
        std::printf("ParaView: open %s (Warp By Vector on displacement shows the motion)\n",
                    f.path.c_str());
      }
    }
  }
  if (!any) throw CliError(kExitFailure, "job " + job.id() + " has no files to fetch");
  return kExitOk;
}

}  // namespace softshock::cli
