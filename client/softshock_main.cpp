// softshock: command-line client of softshockd (docs: client/README.md).
//
//   softshock [--server HOST:PORT] [--token-file F] [--tls-ca F] [--json] [--timeout S]
//             COMMAND [ARGS]
//
// Exit codes: 0 success, 1 server-side failure / unreachable / job did not succeed, 2 usage or
// invalid input (including INVALID_ARGUMENT from the server). Errors are one line on stderr:
// "softshock: COMMAND: message (GRPC_CODE)".
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>
#include <vector>

#include "client/commands.hpp"
#include "softshock/version.hpp"

namespace softshock::cli {
namespace {

const std::vector<OptionSpec> kGlobalOptions = {
    {"server", true},  {"token-file", true}, {"tls-ca", true},   {"json", false},
    {"timeout", true}, {"help", false},      {"version", false},
};

const std::vector<Command>& commands() {
  static const std::vector<Command> table = {
      {"submit",
       "SPEC.json [--label k=v]... [--priority N] [--request-id ID] [--wait]",
       "submit a run spec (protobuf JSON, '-' = stdin); prints the job id",
       {{"label", true}, {"priority", true}, {"request-id", true}, {"wait", false}},
       1,
       1,
       cmd_submit},
      {"extend",
       "ID --end-time T [--label k=v]... [--priority N] [--request-id ID] [--wait]",
       "continue a SUCCEEDED job to a later end time as a new job (its id printed; parent_id\n"
       "           links it), starting from where the job stopped when its state was kept",
       {{"end-time", true},
        {"label", true},
        {"priority", true},
        {"request-id", true},
        {"wait", false}},
       1,
       1,
       cmd_extend},
      {"status", "ID", "show a job", {}, 1, 1, cmd_status},
      {"watch", "ID", "follow a job to its end (exit 0 only if it SUCCEEDED)", {}, 1, 1, cmd_watch},
      {"list",
       "[--state S] [--label k=v] [--owner USER | --mine] [--since T] [--until T]\n"
       "                 [--fields PATH,...] [--format table|csv|json] [--limit N]",
       "list jobs, newest first, with state reason, elapsed time and owner (--limit 0 = all;\n"
       "           default 100); --mine: your own; --since/--until: created after/before a time\n"
       "           (2026-12-04, 2026-12-04T17:00:00Z, or an age: 30min, 2h, 3d); --fields adds\n"
       "           spec fields as columns (material.shear_viscosity,load.pressure)",
       {{"state", true},
        {"label", true},
        {"owner", true},
        {"mine", false},
        {"limit", true},
        {"since", true},
        {"until", true},
        {"fields", true},
        {"format", true}},
       0,
       0,
       cmd_list},
      {"label",
       "ID KEY=VALUE... [-KEY]...",
       "set labels of a job (your own; an admin: any) and remove them (-KEY)",
       {{"remove", true}},
       1,
       128,
       cmd_label},
      {"fetch",
       "ID [DIR] [--file h5|xdmf|spec|summary]...",
       "download a finished job's result.h5, result.xdmf, spec.json and summary.json into DIR\n"
       "           (default ./ID); resumes a partial download, checks SHA-256; ParaView opens\n"
       "           DIR/result.xdmf",
       {{"file", true}},
       1,
       2,
       cmd_fetch},
      {"diff",
       "A B [--png FILE]",
       "compare two jobs: the spec fields that differ (after defaults), the summary figures\n"
       "           side by side with B's relative difference; --png: A-bar(t) of both",
       {{"png", true}},
       2,
       2,
       cmd_diff},
      {"cancel",
       "ID",
       "cancel a queued or running job (your own; an admin: any)",
       {},
       1,
       1,
       cmd_cancel},
      {"delete",
       "ID",
       "delete a job and its results (your own; an admin: any)",
       {},
       1,
       1,
       cmd_delete},
      {"summary",
       "ID",
       "the run's figures (energies, A-bar, modes, shock times)",
       {},
       1,
       1,
       cmd_summary},
      {"modes",
       "ID [--csv] [--every K] [--mode-min A --mode-max B] [--png FILE]",
       "Fourier mode amplitudes of the rim over time; --png: heat map over mode number x t-bar",
       {{"csv", false}, {"every", true}, {"mode-min", true}, {"mode-max", true}, {"png", true}},
       1,
       1,
       cmd_modes},
      {"series",
       "ID [ID]... [--csv] [--every K] [--name N]... [--png FILE]",
       "time series (A-bar, energies, ...); --png: A-bar(t) of one or several jobs",
       {{"csv", false}, {"every", true}, {"name", true}, {"png", true}},
       1,
       64,
       cmd_series},
      {"field",
       "ID --name J|mean_stress|hoop_stress|radial_stress|von_mises|displacement|velocity|damage\n"
       "                 [--time T | --frame K] [--raster NXxNY | --every K | --surface N]\n"
       "                 [--slice z=V | --slice PX,PY,PZ:NX,NY,NZ] [--csv FILE] [--png FILE]",
       "a field frame: statistics, CSV ('-' = stdout) or a PNG plot (raster, default 256x256); "
       "3-D results: --slice samples a plane (default z = 0), --surface N the deformed boundary "
       "decimated to N triangles",
       {{"name", true},
        {"time", true},
        {"frame", true},
        {"raster", true},
        {"every", true},
        {"slice", true},
        {"surface", true},
        {"csv", true},
        {"png", true}},
       1,
       1,
       cmd_field},
      {"grid",
       "submit GRID.json [--wait] [--label k=v]... [--priority N] [--request-id ID] "
       "[--recompute]\n"
       "                 | status ID | wait ID | list [--owner USER | --mine] | cancel ID\n"
       "                 | reduce ID [--quantity Q] [--tbar T] [--csv] [--png FILE]",
       "parameter grids: submit (a base spec x 1-3 axes), follow, cancel, reduce to a table,\n"
       "           CSV or heat map (quantities: 'softshock figures --grid', default\n"
       "           max_abar_first_cycle, and abar_at --tbar T; the older energy_injected, ...\n"
       "           still work)",
       {{"wait", false},
        {"label", true},
        {"priority", true},
        {"request-id", true},
        {"recompute", false},
        {"quantity", true},
        {"tbar", true},
        {"csv", false},
        {"png", true},
        {"owner", true},
        {"mine", false}},
       1,
       2,
       cmd_grid},
      {"mesh",
       "upload FILE.msh | list [--owner USER | --mine] | delete ID",
       "meshes on the daemon for geometry.mesh_id (upload prints the id; the same bytes give\n"
       "           the same id). submit and grid submit upload a local geometry.mesh_file "
       "themselves",
       {{"owner", true}, {"mine", false}},
       1,
       2,
       cmd_mesh},
      {"query",
       "[--where 'NAME OP VALUE']... [--state S] [--grid ID] [--owner USER | --mine]\n"
       "                 [--order-by 'NAME [desc]'] [--limit N] [--csv]",
       "catalogued jobs whose groups / summary figures pass filters, e.g. --where 'pbar=0.5..1.5'\n"
       "           --where 'gamma>6' --where 'max_abar_first_cycle>0.01' (names: 'softshock\n"
       "           figures --query')",
       {{"where", true},
        {"state", true},
        {"grid", true},
        {"order-by", true},
        {"limit", true},
        {"csv", false},
        {"owner", true},
        {"mine", false}},
       0,
       0,
       cmd_query},
      {"whoami", "", "the user and role your token names on the daemon", {}, 0, 0, cmd_whoami},
      {"figures",
       "[--query | --grid]",
       "the summary figures the daemon reports: unit, meaning, and which query --where and\n"
       "           grid reduce --quantity take (--query, --grid: only those)",
       {{"query", false}, {"grid", false}},
       0,
       0,
       cmd_figures},
      {"health",
       "[--service NAME]",
       "grpc.health.v1 check (exit 0 when SERVING)",
       {{"service", true}},
       0,
       0,
       cmd_health},
  };
  return table;
}

void print_usage(std::FILE* out) {
  std::fprintf(out,
               "usage: softshock [--server HOST:PORT] [--token-file FILE] [--tls-ca FILE] "
               "[--json] [--timeout S] COMMAND [ARGS]\n"
               "       softshock --help | --version\n\n"
               "  --server      daemon address (env SOFTSHOCK_SERVER; default 127.0.0.1:50051)\n"
               "  --token-file  send 'authorization: Bearer TOKEN' (token read from FILE)\n"
               "  --tls-ca      use TLS, trusting this root CA (PEM); default: plaintext\n"
               "  --json        print responses in protobuf's JSON mapping\n"
               "  --timeout     deadline per call in seconds (default 30; 0 = none); watch has "
               "no deadline\n                but reconnects across daemon restarts for this "
               "long\n\ncommands:\n");
  for (const auto& c : commands()) {
    std::fprintf(out, "  %-8s %s\n           %s\n", c.name, c.synopsis, c.help);
  }
  std::fprintf(out,
               "\ntimes for --time take a unit suffix (40ns, 0.04us) or are in seconds.\n"
               "exit codes: 0 ok, 1 server-side failure or job not SUCCEEDED, 2 usage or "
               "invalid input\n");
}

void apply_global(GlobalOptions& g, const ParsedArgs& parsed) {
  if (auto s = parsed.get("server")) g.server = *s;
  if (auto t = parsed.get("token-file")) g.token_file = *t;
  if (auto c = parsed.get("tls-ca")) g.tls_ca = *c;
  if (parsed.has("json")) g.json = true;
  if (auto t = parsed.get("timeout")) {
    g.timeout_s = parse_double("timeout", *t);
    if (g.timeout_s < 0) usage_error("--timeout: must be >= 0");
  }
  if (g.server.empty()) usage_error("--server: empty address");
}

int run(int argc, char** argv, std::string& command_name) {
  std::vector<std::string> args(argv + 1, argv + argc);
  GlobalOptions g;
  if (const char* env = std::getenv("SOFTSHOCK_SERVER"); env && *env) g.server = env;

  // Global options come before the command word; they are also accepted after it (users put
  // --json at the end), so the command's option table is extended with them below.
  std::size_t i = 0;
  std::vector<std::string> leading;
  while (i < args.size() && args[i].rfind("-", 0) == 0 && args[i] != "-") {
    leading.push_back(args[i]);
    const std::string name = args[i].substr(2, args[i].find('=') - 2);
    bool needs_value =
        args[i].find('=') == std::string::npos &&
        (name == "server" || name == "token-file" || name == "tls-ca" || name == "timeout");
    ++i;
    if (needs_value && i < args.size()) leading.push_back(args[i++]);
  }
  ParsedArgs global = parse_options(leading, kGlobalOptions);
  if (global.has("version")) {
    std::printf("softshock %s\n", kVersion);
    return kExitOk;
  }
  if (global.has("help") || i == args.size()) {
    print_usage(global.has("help") ? stdout : stderr);
    return global.has("help") ? kExitOk : kExitUsage;
  }
  command_name = args[i];
  if (command_name == "help") {
    print_usage(stdout);
    return kExitOk;
  }
  const Command* cmd = nullptr;
  for (const auto& c : commands()) {
    if (command_name == c.name) cmd = &c;
  }
  if (cmd == nullptr) {
    std::string unknown = command_name;
    command_name.clear();
    usage_error("unknown command '" + unknown + "' (softshock --help lists them)");
  }
  std::vector<OptionSpec> specs = cmd->options;
  specs.insert(specs.end(), kGlobalOptions.begin(), kGlobalOptions.end());
  // `label ID -KEY` removes KEY: there a word with one dash is an argument, not an option.
  ParsedArgs parsed = parse_options(std::vector<std::string>(args.begin() + i + 1, args.end()),
                                    specs, /*single_dash_words=*/command_name == "label");
  if (parsed.has("help")) {
    std::printf("usage: softshock %s %s\n  %s\n", cmd->name, cmd->synopsis, cmd->help);
    return kExitOk;
  }
  apply_global(g, global);
  apply_global(g, parsed);
  if (parsed.positional.size() < cmd->min_positional ||
      parsed.positional.size() > cmd->max_positional) {
    usage_error(std::string("usage: softshock ") + cmd->name + " " + cmd->synopsis);
  }
  for (const auto& p : parsed.positional) {
    if (p.empty()) usage_error("empty argument");
  }
  return cmd->run(g, parsed);
}

}  // namespace
}  // namespace softshock::cli

namespace {

// The error contract is one line on stderr (scripts grep it; log collectors split on lines),
// but some messages span several (protobuf's JSON parser adds the offending text and a caret).
std::string one_line(const std::string& message) {
  std::string out;
  std::size_t start = 0;
  while (start <= message.size()) {
    std::size_t end = message.find('\n', start);
    if (end == std::string::npos) end = message.size();
    std::string part = softshock::cli::trim(std::string_view(message).substr(start, end - start));
    // A line of only a caret points into the previous line; without the layout it means nothing.
    if (!part.empty() && part != "^") out += (out.empty() ? "" : "; ") + part;
    start = end + 1;
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  std::string command;
  try {
    return softshock::cli::run(argc, argv, command);
  } catch (const softshock::cli::CliError& e) {
    std::fflush(stdout);
    std::fprintf(stderr, "softshock: %s%s%s\n", command.c_str(), command.empty() ? "" : ": ",
                 one_line(e.what()).c_str());
    return e.exit_code();
  } catch (const std::exception& e) {
    std::fflush(stdout);
    std::fprintf(stderr, "softshock: %s%sinternal error: %s\n", command.c_str(),
                 command.empty() ? "" : ": ", one_line(e.what()).c_str());
    return softshock::cli::kExitFailure;
  }
}
