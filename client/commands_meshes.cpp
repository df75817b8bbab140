// `softshock mesh upload|list|delete` and the automatic upload of a spec's local mesh file.
#include <cstdio>
#include <filesystem>

#include "client/commands.hpp"
#include "client/format.hpp"

namespace softshock::cli {

namespace fs = std::filesystem;

namespace {

constexpr std::size_t kChunkBytes = 1 << 20;  // well under gRPC's 4 MiB message limit

v1::Mesh upload(Connection& conn, const std::string& path) {
  const std::string bytes = read_file(path);
  v1::Mesh mesh;
  // Retried as a whole on UNAVAILABLE: the upload is idempotent (content-addressed).
  conn.unary([&](grpc::ClientContext& ctx) {
    auto writer = conn.meshes().UploadMesh(&ctx, &mesh);
    v1::UploadMeshRequest part;
    part.set_file_name(fs::path(path).filename().string());
    std::size_t offset = 0;
    do {
      part.set_data(bytes.substr(offset, kChunkBytes));
      offset += kChunkBytes;
      if (!writer->Write(part)) break;  // the server ended the call; Finish() says why
      part.clear_file_name();
    } while (offset < bytes.size());
    writer->WritesDone();
    return writer->Finish();
  });
  return mesh;
}

void print_mesh(const v1::Mesh& m) {
  std::printf("%s  %8lld elements  %8lld nodes  %10lld bytes  %s  %-12s  %s\n", m.id().c_str(),
              static_cast<long long>(m.elements()), static_cast<long long>(m.nodes()),
              static_cast<long long>(m.size_bytes()), fmt_timestamp(m.create_time()).c_str(),
              m.owner().empty() ? "-" : m.owner().c_str(), m.file_name().c_str());
}

}  // namespace

void upload_local_mesh(Connection& conn, const std::string& spec_path, v1::RunSpec* spec) {
  if (spec->geometry().shape_case() != v1::Geometry::kMeshFile) return;
  const fs::path named(spec->geometry().mesh_file());
  const fs::path base = spec_path == "-" ? fs::current_path() : fs::path(spec_path).parent_path();
  const fs::path local = named.is_absolute() ? named : base / named;
  std::error_code ec;
  if (!fs::is_regular_file(local, ec)) {
    // An absolute path can only mean this machine: say so here rather than as a server error.
    if (named.is_absolute()) {
      usage_error("geometry.mesh_file: '" + named.string() + "' is not a file on this machine");
    }
    return;  // a file in the daemon's DATA/meshes/
  }
  const v1::Mesh mesh = upload(conn, local.string());
  std::fprintf(stderr, "softshock: uploaded %s as meshes/%s (%lld elements)\n",
               local.string().c_str(), mesh.id().c_str(), static_cast<long long>(mesh.elements()));
  spec->mutable_geometry()->clear_shape();  // mesh_id sits outside the shape oneof
  spec->mutable_geometry()->set_mesh_id(mesh.id());
}

int cmd_mesh(const GlobalOptions& g, const ParsedArgs& a) {
  const std::string& sub = a.positional.at(0);
  auto need = [&](std::size_t n, const char* usage) {
    if (a.positional.size() != n) usage_error(std::string("usage: softshock mesh ") + usage);
  };
  if (sub == "upload") {
    need(2, "upload FILE.msh");
    Connection conn(g);
    const v1::Mesh mesh = upload(conn, a.positional[1]);
    std::printf("%s\n", g.json ? to_json(mesh).c_str() : mesh.id().c_str());
    return kExitOk;
  }
  if (sub == "list") {
    need(1, "list [--owner USER | --mine]");
    Connection conn(g);
    v1::ListMeshesRequest request;
    request.set_owner(owner_filter(conn, a));
    auto all = collect_pages<v1::ListMeshesRequest, v1::ListMeshesResponse>(
        conn, request, 0,
        [&](grpc::ClientContext& ctx, const v1::ListMeshesRequest& r, v1::ListMeshesResponse& p) {
          return conn.meshes().ListMeshes(&ctx, r, &p);
        },
        [](v1::ListMeshesResponse& r) { return r.mutable_meshes(); });
    if (g.json) {
      std::printf("%s\n", to_json(all).c_str());
    } else if (all.meshes().empty()) {
      const std::string by = request.owner().empty() ? "" : " by " + request.owner();
      std::printf("no meshes uploaded%s (softshock mesh upload FILE.msh)\n", by.c_str());
    } else {
      for (const auto& m : all.meshes()) print_mesh(m);
    }
    return kExitOk;
  }
  if (sub == "delete") {
    need(2, "delete ID");
    Connection conn(g);
    v1::DeleteMeshRequest request;
    request.set_name(a.positional[1]);
    v1::DeleteMeshResponse response;
    conn.unary([&](grpc::ClientContext& ctx) {
      return conn.meshes().DeleteMesh(&ctx, request, &response);
    });
    const std::string& given = a.positional[1];
    const std::string name = given.rfind("meshes/", 0) == 0 ? given : "meshes/" + given;
    if (g.json) {
      std::printf("%s\n", to_json(response).c_str());
    } else {
      std::printf("deleted: %s\n", name.c_str());
    }
    return kExitOk;
  }
  usage_error("mesh: unknown subcommand '" + sub + "' (upload, list, delete)");
}

}  // namespace softshock::cli
