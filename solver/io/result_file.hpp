// HDF5 result files (layout: docs/results-format.md) and their XDMF companion.
// libhdf5 is not thread-safe: every HDF5 call in this module holds one process-wide mutex, so
// several runs (daemon workers) may write and read result files concurrently.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "solver/mesh.hpp"
#include "solver/run_summary.hpp"
#include "solver/simulation.hpp"

namespace softshock {

// Writes DIR/result.h5 (+ DIR/result.xdmf). Data goes to DIR/result.h5.tmp; finish() flushes,
// fsyncs and renames, so a reader never sees a half-written result.h5.
class ResultWriter {
 public:
  // kLater: the constructor creates the file and its attributes only, and write_mesh() adds
  // /mesh (before finish(), which refuses a file without it) -- so that a writer thread can
  // take that work off the thread that creates the writer.
  enum class MeshWrite { kNow, kLater };
  ResultWriter(const std::string& out_dir, const Mesh& mesh, const std::string& spec_json,
               const std::string& solver_version, MeshWrite when = MeshWrite::kNow);
  // A run continued from a checkpoint: its frames so far are in sealed files (seal_segment; the
  // first one holds /mesh), the frames to come go to a new temporary file, and finish() copies
  // the sealed mesh and frames in. Each sealed file is opened and its frames checked now
  // (std::runtime_error if one is missing or unreadable).
  struct Sealed {
    std::string path;        // an HDF5 file of this run's layout
    std::size_t frames = 0;  // its frames, numbered on from the previous file's
  };
  ResultWriter(const std::string& out_dir, const Mesh& mesh, const std::string& spec_json,
               const std::string& solver_version, const std::vector<Sealed>& sealed,
               const std::vector<double>& frame_times);
  ~ResultWriter();  // without finish(): closes and removes the temporary file
  ResultWriter(const ResultWriter&) = delete;
  ResultWriter& operator=(const ResultWriter&) = delete;

  void write_mesh(const Mesh& mesh);          // MeshWrite::kLater: /mesh, once
  void write_frame(const FieldFrame& frame);  // /fields/frame_00000, _00001, ...
  // For a checkpoint: closes the temporary file with the frames written since the last seal (and
  // the mesh, the first time), makes it durable under `path` (a name on the same filesystem,
  // not this folder's result.h5) and opens a new temporary file for the frames to come. What is
  // sealed is never written again: finish() copies it into the result.
  void seal_segment(const std::string& path);
  const std::vector<Sealed>& sealed() const;
  const std::vector<double>& frame_times() const;  // s, every frame so far, sealed or not
  // Writes /timeseries, /modes, root attributes (run statistics, summary JSON, `complete`,
  // `error`), then makes the files durable under their final names.
  void finish(const History& history, const RunSummary& summary, bool complete,
              const std::string& error);

  std::string h5_path() const;    // final path DIR/result.h5
  std::string xdmf_path() const;  // DIR/result.xdmf

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Read side, for the daemon's queries and for tests.
// Gives out_dir the finished result files of another run (result.h5 and result.xdmf next to
// source_h5): hard links, since finished files never change and a link survives the source's
// deletion; copies where linking is impossible (another filesystem). Durable on return.
// Returns out_dir/result.h5. Throws std::runtime_error.
std::string link_result_files(const std::string& source_h5, const std::string& out_dir);

struct ResultInfo {
  bool complete = false;
  std::string error, spec_json, summary_json, solver_version;
  std::vector<double> frame_times;  // s, one per /fields/frame_K
  // The mesh's: 2 (triangles) or 3 (tetrahedra); 2 for files written before 3-D results, which
  // have no `dimension` attribute.
  int dimension = 2;
  std::size_t nodes = 0, elements = 0;  // elements: triangles in 2-D, tetrahedra in 3-D
};

class ResultReader {
 public:
  explicit ResultReader(const std::string& h5_path);  // throws std::runtime_error
  ~ResultReader();
  ResultReader(const ResultReader&) = delete;
  ResultReader& operator=(const ResultReader&) = delete;

  const ResultInfo& info() const;
  // 2-D: nodes, triangles, boundary_nodes (boundary_edges rebuilt by finalize_mesh). 3-D: x, y,
  // z, tetrahedra and boundary_faces as stored (node indices checked, nothing rebuilt).
  Mesh mesh() const;
  // Scalar series by name (e.g. "abar"); "time" is the shared time axis.
  std::vector<double> series(const std::string& name) const;
  std::vector<std::string> series_names() const;
  std::vector<double> mode_times() const;
  // Row-major T x (M+1) amplitudes.
  std::vector<double> mode_amplitudes(std::size_t& rows, std::size_t& cols) const;
  // Reading only what an answer needs (bounded memory, a short hold of the HDF5 lock): the
  // dimensions of a dataset ("/timeseries/abar", "/modes/amplitude"; 1 or 2 entries), and
  // rows first, first + stride, ... (`rows` of them) x columns col_first.. (col_count of them;
  // a 1-D dataset has one column), row-major. Throws std::runtime_error for a range outside.
  std::vector<std::size_t> dims(const std::string& dataset) const;
  struct Slice {
    std::size_t first = 0, stride = 1, rows = 0, col_first = 0, col_count = 1;
  };
  std::vector<double> slice(const std::string& dataset, const Slice& s) const;
  // A field of frame k: "displacement" and "velocity" are N x dimension interleaved (2-D: N x 2
  // whatever the format_version, the stored z = 0 column of version 2 dropped; 3-D: N x 3);
  // "J", "mean_stress", "radial_stress", "hoop_stress", "von_mises", "aspect_ratio" are per
  // element; "damage" (runs with phase-field damage only) per node, N values.
  std::vector<double> field(std::size_t frame, const std::string& name) const;

 private:
  Mesh mesh_3d() const;
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace softshock
