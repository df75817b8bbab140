// The catalogue's schema: ordered migrations, applied at open in one transaction.
#include "server/store/catalogue_schema.hpp"

#include <cstdint>
#include <iterator>
#include <string_view>

#include "server/policy/users.hpp"

namespace softshock::server::detail {
namespace {

// Migration 8 writes the default owner as a literal.
static_assert(std::string_view(kDefaultUser) == "default");

// Ordered migrations: entry k brings the schema from version k to k + 1. Never edit a shipped
// entry; append a new one.
const char* const kMigrations[] = {
    R"sql(
CREATE TABLE jobs (
  seq INTEGER PRIMARY KEY AUTOINCREMENT,
  id TEXT NOT NULL UNIQUE,
  state INTEGER NOT NULL,
  spec_json TEXT NOT NULL,
  spec_hash TEXT NOT NULL,
  priority INTEGER NOT NULL DEFAULT 0,
  request_id TEXT UNIQUE,
  create_time_us INTEGER NOT NULL,
  start_time_us INTEGER NOT NULL DEFAULT 0,
  finish_time_us INTEGER NOT NULL DEFAULT 0,
  progress_fraction REAL NOT NULL DEFAULT 0,
  progress_time REAL NOT NULL DEFAULT 0,
  progress_steps INTEGER NOT NULL DEFAULT 0,
  progress_dt REAL NOT NULL DEFAULT 0,
  error TEXT NOT NULL DEFAULT '',
  reason TEXT NOT NULL DEFAULT '',
  attempt INTEGER NOT NULL DEFAULT 1,
  result_path TEXT NOT NULL DEFAULT ''
);
CREATE INDEX jobs_state ON jobs(state, priority DESC, seq);
CREATE INDEX jobs_created ON jobs(create_time_us);
CREATE INDEX jobs_spec_hash ON jobs(spec_hash);
CREATE TABLE job_labels (
  job_id TEXT NOT NULL REFERENCES jobs(id) ON DELETE CASCADE,
  key TEXT NOT NULL,
  value TEXT NOT NULL,
  PRIMARY KEY (job_id, key)
);
CREATE INDEX job_labels_key_value ON job_labels(key, value);
CREATE TABLE job_attempts (
  job_id TEXT NOT NULL REFERENCES jobs(id) ON DELETE CASCADE,
  attempt INTEGER NOT NULL,
  start_time_us INTEGER NOT NULL,
  end_time_us INTEGER NOT NULL DEFAULT 0,
  outcome TEXT NOT NULL DEFAULT '',
  reason TEXT NOT NULL DEFAULT '',
  error TEXT NOT NULL DEFAULT ''
);
CREATE INDEX job_attempts_job ON job_attempts(job_id);
CREATE TABLE job_summaries (
  job_id TEXT PRIMARY KEY REFERENCES jobs(id) ON DELETE CASCADE,
  elements INTEGER NOT NULL,
  nodes INTEGER NOT NULL,
  steps INTEGER NOT NULL,
  wall_time REAL NOT NULL,
  end_time REAL NOT NULL,
  pbar REAL NOT NULL,
  tbar_pulse REAL NOT NULL,
  mubar REAL NOT NULL,
  gamma REAL NOT NULL,
  c1 REAL NOT NULL,
  c2 REAL NOT NULL,
  time_scale REAL NOT NULL,
  energy_injected REAL NOT NULL,
  energy_after_pulse REAL NOT NULL,
  max_abar_first_cycle REAL NOT NULL,
  max_abar REAL NOT NULL,
  dominant_mode_end INTEGER NOT NULL,
  shock_at_center REAL NOT NULL,
  rim_reflections BLOB,
  min_dt REAL NOT NULL,
  max_dt REAL NOT NULL,
  status TEXT NOT NULL,
  error TEXT NOT NULL,
  mode_count INTEGER NOT NULL,
  mode_times BLOB,
  mode_amplitudes BLOB
);
CREATE INDEX job_summaries_max_abar ON job_summaries(max_abar);
)sql",
    // 1 -> 2: parameter grids, result reuse, and what QueryJobs filters on. The groups
    // (known at submission, made exact from the summary when a run finishes) and the summary
    // figures are copied onto jobs, so a query is pure SQL over indexed columns of one narrow
    // table: a job_summaries row spans a page or more (its mode amplitudes), and filtering on
    // it would read one page per job. Existing jobs: groups from their summary, or
    // from the stored spec where that needs no square root (SQLite's math functions are a
    // build option); t-bar_pulse of older unfinished jobs stays NULL until they finish.
    R"sql(
ALTER TABLE jobs ADD COLUMN grid_id TEXT;
ALTER TABLE jobs ADD COLUMN grid_index INTEGER NOT NULL DEFAULT 0;
ALTER TABLE jobs ADD COLUMN reused_from TEXT NOT NULL DEFAULT '';
ALTER TABLE jobs ADD COLUMN reuse_result INTEGER NOT NULL DEFAULT 0;
ALTER TABLE jobs ADD COLUMN pbar REAL;
ALTER TABLE jobs ADD COLUMN tbar_pulse REAL;
ALTER TABLE jobs ADD COLUMN mubar REAL;
ALTER TABLE jobs ADD COLUMN gamma REAL;
ALTER TABLE jobs ADD COLUMN c1 REAL;
ALTER TABLE jobs ADD COLUMN c2 REAL;
UPDATE jobs SET
  pbar = json_extract(spec_json, '$.load.pressure') / json_extract(spec_json, '$.material.bulk_modulus'),
  mubar = json_extract(spec_json, '$.material.shear_modulus') / json_extract(spec_json, '$.material.bulk_modulus'),
  gamma = json_extract(spec_json, '$.material.tait_gamma'),
  c1 = json_extract(spec_json, '$.viscosity.c1'),
  c2 = json_extract(spec_json, '$.viscosity.c2')
  WHERE json_valid(spec_json);
ALTER TABLE jobs ADD COLUMN max_abar_first_cycle REAL;
ALTER TABLE jobs ADD COLUMN max_abar REAL;
ALTER TABLE jobs ADD COLUMN energy_injected REAL;
ALTER TABLE jobs ADD COLUMN energy_after_pulse REAL;
ALTER TABLE jobs ADD COLUMN dominant_mode_end INTEGER;
ALTER TABLE jobs ADD COLUMN shock_at_center REAL;
ALTER TABLE jobs ADD COLUMN wall_time REAL;
ALTER TABLE jobs ADD COLUMN elements INTEGER;
ALTER TABLE jobs ADD COLUMN steps INTEGER;
UPDATE jobs SET (pbar, tbar_pulse, mubar, gamma, c1, c2, max_abar_first_cycle, max_abar,
                 energy_injected, energy_after_pulse, dominant_mode_end, shock_at_center,
                 wall_time, elements, steps) =
  (SELECT s.pbar, s.tbar_pulse, s.mubar, s.gamma, s.c1, s.c2, s.max_abar_first_cycle, s.max_abar,
          s.energy_injected, s.energy_after_pulse, s.dominant_mode_end, s.shock_at_center,
          s.wall_time, s.elements, s.steps FROM job_summaries s WHERE s.job_id = jobs.id)
  WHERE EXISTS (SELECT 1 FROM job_summaries s WHERE s.job_id = jobs.id);
CREATE INDEX jobs_grid ON jobs(grid_id, grid_index) WHERE grid_id IS NOT NULL;
CREATE INDEX jobs_pbar ON jobs(pbar);
CREATE INDEX jobs_tbar_pulse ON jobs(tbar_pulse);
CREATE INDEX jobs_mubar ON jobs(mubar);
CREATE INDEX jobs_gamma ON jobs(gamma);
CREATE INDEX jobs_c1 ON jobs(c1);
CREATE INDEX jobs_c2 ON jobs(c2);
CREATE INDEX jobs_max_abar_first_cycle ON jobs(max_abar_first_cycle);
CREATE INDEX jobs_max_abar ON jobs(max_abar);
CREATE INDEX jobs_energy_injected ON jobs(energy_injected);
CREATE INDEX jobs_dominant_mode_end ON jobs(dominant_mode_end);
ALTER TABLE job_summaries ADD COLUMN abar_times BLOB;
ALTER TABLE job_summaries ADD COLUMN abar_values BLOB;
CREATE TABLE grids (
  seq INTEGER PRIMARY KEY AUTOINCREMENT,
  id TEXT NOT NULL UNIQUE,
  request_id TEXT UNIQUE,
  create_time_us INTEGER NOT NULL,
  point_count INTEGER NOT NULL,
  cancelled INTEGER NOT NULL DEFAULT 0,
  definition TEXT NOT NULL
);
)sql",
    // 2 -> 3: the slurm executor (server/slurm_executor.hpp). The Slurm job id ("123" or
    // "123_4" for an array task) of a job handed to Slurm; '' = not submitted (always so under
    // the local executor). A job with an id is re-attached at start-up, never run again.
    R"sql(
ALTER TABLE jobs ADD COLUMN slurm_job_id TEXT NOT NULL DEFAULT '';
CREATE INDEX jobs_slurm_job_id ON jobs(slurm_job_id) WHERE slurm_job_id != '';
)sql",
    // 3 -> 4: where a run's time went (RunSummary): the element loop alone, the meshing before
    // the run and whether the mesh came from the cache. Older rows: 0 and 'not-used'.
    R"sql(
ALTER TABLE job_summaries ADD COLUMN kernel_time REAL NOT NULL DEFAULT 0;
ALTER TABLE job_summaries ADD COLUMN meshing_time REAL NOT NULL DEFAULT 0;
ALTER TABLE job_summaries ADD COLUMN mesh_cache TEXT NOT NULL DEFAULT 'not-used';
)sql",
    // 4 -> 5: the late-time figures (RunSummary): A-bar at the end and the filtered A-bar (rebuilt
    // from the low modes), the largest element aspect ratio and when it first exceeded 10
    // (-1 = never). Older rows: 0, and -1 for the time.
    R"sql(
ALTER TABLE job_summaries ADD COLUMN max_abar_filtered_first_cycle REAL NOT NULL DEFAULT 0;
ALTER TABLE job_summaries ADD COLUMN max_abar_filtered REAL NOT NULL DEFAULT 0;
ALTER TABLE job_summaries ADD COLUMN abar_end REAL NOT NULL DEFAULT 0;
ALTER TABLE job_summaries ADD COLUMN abar_filtered_end REAL NOT NULL DEFAULT 0;
ALTER TABLE job_summaries ADD COLUMN max_aspect_ratio REAL NOT NULL DEFAULT 0;
ALTER TABLE job_summaries ADD COLUMN aspect_ratio_above_10 REAL NOT NULL DEFAULT -1;
)sql",
    // 5 -> 6: the revision of the solver that produced the summary (RunSummary::solver_revision;
    // results are reused only from the running one). Older rows: 0, so none is reused.
    R"sql(
ALTER TABLE job_summaries ADD COLUMN solver_revision INTEGER NOT NULL DEFAULT 0;
)sql",
    // 6 -> 7: the rest of where a run's time went (RunSummary): the solver thread's wall time in
    // diagnostics and in handing frames to the writer. Older rows: 0.
    R"sql(
ALTER TABLE job_summaries ADD COLUMN diagnostics_time REAL NOT NULL DEFAULT 0;
ALTER TABLE job_summaries ADD COLUMN output_time REAL NOT NULL DEFAULT 0;
)sql",
    // 7 -> 8: owners (server/policy/): the user who submitted a job or grid. Rows of a data
    // folder from before users existed belong to the default user, which is also the single
    // --token-file user's name unless --token-user says otherwise. The index serves the per-user
    // queue bound (owner's QUEUED jobs, counted at every submission) and the owner filters.
    R"sql(
ALTER TABLE jobs ADD COLUMN owner TEXT NOT NULL DEFAULT 'default';
ALTER TABLE grids ADD COLUMN owner TEXT NOT NULL DEFAULT 'default';
CREATE INDEX jobs_owner_state ON jobs(owner, state);
)sql",
    // 8 -> 9: phase-field damage's summary figures (RunSummary; 0 / -1 without damage, as the
    // rows of runs from before it existed).
    R"sql(
ALTER TABLE job_summaries ADD COLUMN damage INTEGER NOT NULL DEFAULT 0;
ALTER TABLE job_summaries ADD COLUMN damage_onset REAL NOT NULL DEFAULT -1;
ALTER TABLE job_summaries ADD COLUMN max_damaged_volume REAL NOT NULL DEFAULT 0;
ALTER TABLE job_summaries ADD COLUMN max_damaged_radius REAL NOT NULL DEFAULT 0;
ALTER TABLE job_summaries ADD COLUMN damage_dissipation REAL NOT NULL DEFAULT 0;
ALTER TABLE job_summaries ADD COLUMN crack_energy REAL NOT NULL DEFAULT 0;
ALTER TABLE job_summaries ADD COLUMN damage_time REAL NOT NULL DEFAULT 0;
ALTER TABLE job_summaries ADD COLUMN damage_solves INTEGER NOT NULL DEFAULT 0;
)sql",
    // 9 -> 10: ExtendJob's link from a job to the SUCCEEDED job it continues; the summary's
    // dimension and 3-D thickness (rows from before: 2-D).
    R"sql(
ALTER TABLE jobs ADD COLUMN parent_id TEXT NOT NULL DEFAULT '';
ALTER TABLE job_summaries ADD COLUMN dimension INTEGER NOT NULL DEFAULT 2;
ALTER TABLE job_summaries ADD COLUMN thickness REAL NOT NULL DEFAULT 0;
)sql",
};

}  // namespace

int catalogue_schema_version() {
  return static_cast<int>(std::size(kMigrations));
}

const char* catalogue_migration(int from) {
  if (from < 0 || from >= catalogue_schema_version()) return nullptr;
  return kMigrations[from];
}

int migrate_catalogue(SqliteConnection& c, const std::string& path) {
  c.exec("CREATE TABLE IF NOT EXISTS schema_version (version INTEGER NOT NULL)");
  SqliteConnection::Transaction tx(c);
  int64_t version = 0;
  bool have_row = false;
  {
    auto s = c.prepare("SELECT version FROM schema_version");
    if (s.step()) {
      version = s.i64(0);
      have_row = true;
    }
  }
  if (!have_row) c.prepare("INSERT INTO schema_version(version) VALUES (0)").run();
  const auto known = static_cast<int64_t>(std::size(kMigrations));
  if (version > known) {
    throw CatalogueError("catalogue " + path + " has schema version " + std::to_string(version) +
                         ", newer than this softshockd (" + std::to_string(known) + ")");
  }
  for (int64_t v = version; v < known; ++v) c.exec(kMigrations[v]);
  c.prepare("UPDATE schema_version SET version = ?").bind(1, known).run();
  tx.commit();
  return static_cast<int>(known);
}

}  // namespace softshock::server::detail
