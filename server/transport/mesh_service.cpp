#include "server/transport/mesh_service.hpp"

#include <grpcpp/grpcpp.h>

#include "server/log.hpp"
#include "server/transport/resource_name.hpp"
#include "server/transport/rpc_guard.hpp"
#include "server/transport/rpc_support.hpp"

namespace softshock::server {

using grpc::Status;
using grpc::StatusCode;

Status MeshService::UploadMesh(grpc::ServerContext* ctx,
                               grpc::ServerReader<v1::UploadMeshRequest>* reader, v1::Mesh* resp) {
  return audited(auth_, ctx, "UploadMesh", [&](const Caller& caller, AuditRecord& audit) -> Status {
    // Each part goes to the staged file as it arrives: an upload never sits whole in memory, and
    // a bounded number run at once (begin_upload refuses more).
    auto upload = store_.begin_upload();
    std::string file_name;
    bool first = true;
    v1::UploadMeshRequest part;
    while (reader->Read(&part)) {
      if (first) {
        file_name = part.file_name().empty() ? "mesh.msh" : part.file_name();
        check_mesh_file_name(file_name);  // before any data is written
        first = false;
      }
      upload->append(part.data());  // stops at the size cap: the rest is never read
    }
    if (ctx->IsCancelled()) return {StatusCode::CANCELLED, "upload cancelled by the client"};
    if (first) throw SpecError("data", "the mesh file is empty");
    *resp = store_.commit(*upload, file_name, caller.user, now_us());
    audit.resource = "meshes/" + resp->id();
    audit.detail = "bytes=" + std::to_string(resp->size_bytes());
    log_info("mesh ", resp->id().substr(0, 12), " uploaded by ", caller.user, " (",
             resp->elements(), " elements, ", resp->size_bytes(), " bytes)");
    return Status::OK;
  });
}

Status MeshService::ListMeshes(grpc::ServerContext* ctx, const v1::ListMeshesRequest* req,
                               v1::ListMeshesResponse* resp) {
  return guarded(auth_, ctx, "ListMeshes", [&]() -> Status {
    if (req->page_size() < 0) {
      return {StatusCode::INVALID_ARGUMENT, "page_size: must not be negative"};
    }
    if (Status s = rpc::check_owner_filter(req->owner()); !s.ok()) return s;
    const int size = req->page_size() == 0 ? 50 : std::min(req->page_size(), 1000);
    // The token is the last id of the previous page (ids sort as the listing does).
    auto page = store_.list(req->page_token(), size + 1, req->owner());
    bool more = static_cast<int>(page.size()) > size;
    if (more) page.pop_back();
    rpc::PageBudget budget;
    for (auto& m : page) {
      if (!budget.take(m.ByteSizeLong())) {
        more = true;
        break;
      }
      *resp->add_meshes() = std::move(m);
    }
    if (more) resp->set_next_page_token(resp->meshes().rbegin()->id());
    return Status::OK;
  });
}

Status MeshService::DeleteMesh(grpc::ServerContext* ctx, const v1::DeleteMeshRequest* req,
                               v1::DeleteMeshResponse*) {
  return audited(auth_, ctx, "DeleteMesh", [&](const Caller& caller, AuditRecord& audit) -> Status {
    std::string id;
    if (Status st = requested_id(req->name(), req->id(), "meshes/", &id); !st.ok()) return st;
    audit.resource = "meshes/" + id;
    auto hold = store_.hold_for_delete();  // no submission can start using it meanwhile
    const auto mesh = store_.get(id);
    if (!mesh) return {StatusCode::NOT_FOUND, "mesh meshes/" + id + " not found"};
    require_may_modify(caller, "meshes/" + id, mesh->owner(), "delete");
    if (auto job = job_using_mesh(catalogue_, store_, id)) {
      return {StatusCode::FAILED_PRECONDITION,
              "mesh meshes/" + id + " is used by job jobs/" + *job +
                  ", which is queued or running; delete the mesh once it has finished"};
    }
    store_.remove(id);
    catalogue_.keep_room();
    log_info("mesh ", id.substr(0, 12), " deleted");
    return Status::OK;
  });
}

}  // namespace softshock::server
