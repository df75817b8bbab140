// softshock.v1.MeshService: meshes uploaded by remote clients (server/store/mesh_store.hpp), with
// the same authentication as SimulationService; each mesh is owned by its uploader, who (or an
// admin) alone may delete it, and counts against the uploader's mesh quotas.
#pragma once

#include "server/store/catalogue.hpp"
#include "server/store/mesh_store.hpp"
#include "server/transport/auth.hpp"
#include "softshock/v1/service.grpc.pb.h"

namespace softshock::server {

class MeshService final : public v1::MeshService::Service {
 public:
  MeshService(MeshStore& store, Catalogue& catalogue, const Authenticator& auth)
      : store_(store), catalogue_(catalogue), auth_(auth) {}

  grpc::Status UploadMesh(grpc::ServerContext* ctx,
                          grpc::ServerReader<v1::UploadMeshRequest>* reader,
                          v1::Mesh* resp) override;
  grpc::Status ListMeshes(grpc::ServerContext* ctx, const v1::ListMeshesRequest* req,
                          v1::ListMeshesResponse* resp) override;
  grpc::Status DeleteMesh(grpc::ServerContext* ctx, const v1::DeleteMeshRequest* req,
                          v1::DeleteMeshResponse* resp) override;

 private:
  MeshStore& store_;
  Catalogue& catalogue_;  // which jobs use a mesh; its room is refilled after a deletion
  const Authenticator& auth_;
};

}  // namespace softshock::server
