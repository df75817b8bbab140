// softshockd's configuration layers: precedence flag > env > file > default, the file format,
// and errors that name the key and where the value came from.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <map>

#include "server/daemon_config.hpp"

namespace softshock::server {
namespace {

namespace fs = std::filesystem;

// A fake environment and a scratch folder for config files, so tests never see the real
// process environment (CI may set SOFTSHOCK_* variables of its own).
class DaemonConfigTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("softshock-config-test-" + std::to_string(::getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string write(const std::string& name, const std::string& text) {
    const std::string path = (dir_ / name).string();
    std::ofstream(path) << text;
    return path;
  }

  LoadedConfig load(const std::vector<std::string>& args) {
    return load_daemon_config(args, [this](const char* name) -> const char* {
      const auto it = env_.find(name);
      return it == env_.end() ? nullptr : it->second.c_str();
    });
  }

  // The ConfigError message of a load that must fail.
  std::string error_of(const std::vector<std::string>& args) {
    try {
      load(args);
    } catch (const ConfigError& e) {
      return e.what();
    }
    ADD_FAILURE() << "no ConfigError";
    return "";
  }

  fs::path dir_;
  std::map<std::string, std::string> env_;
};

TEST_F(DaemonConfigTest, DefaultsWithNothingGiven) {
  const LoadedConfig c = load({});
  const DaemonConfig defaults;
  EXPECT_EQ(c.config.data_dir, defaults.data_dir);
  EXPECT_EQ(c.config.listen, defaults.listen);
  EXPECT_EQ(c.config.workers, defaults.workers);
  EXPECT_EQ(c.config.max_attempts, defaults.max_attempts);
  EXPECT_FALSE(c.config.insecure_no_auth);
  EXPECT_TRUE(c.source.empty());
  EXPECT_FALSE(c.help);
  EXPECT_FALSE(c.version);
}

TEST_F(DaemonConfigTest, FlagBeatsEnvBeatsFileBeatsDefault) {
  const std::string file = write("d.conf",
                                 "workers = 3\n"
                                 "max-queued = 30\n"
                                 "max-attempts = 7\n"
                                 "solver-threads = 2\n");
  env_["SOFTSHOCK_WORKERS"] = "4";
  env_["SOFTSHOCK_MAX_QUEUED"] = "40";
  const LoadedConfig c = load({"--config", file, "--workers", "5"});
  EXPECT_EQ(c.config.workers, 5);                                 // flag over env and file
  EXPECT_EQ(c.config.max_queued, 40u);                            // env over file
  EXPECT_EQ(c.config.max_attempts, 7);                            // file over default
  EXPECT_EQ(c.config.solver_threads, 2);                          // file
  EXPECT_EQ(c.config.max_elements, DaemonConfig().max_elements);  // default
  EXPECT_EQ(c.source.at("workers"), "flag --workers");
  EXPECT_EQ(c.source.at("max-queued"), "env SOFTSHOCK_MAX_QUEUED");
  EXPECT_EQ(c.source.at("max-attempts"), "file " + file + ":3");
  EXPECT_EQ(c.source.count("max-elements"), 0u);
  EXPECT_EQ(c.config_file, file);
  EXPECT_EQ(c.source.at("config"), "flag --config");
  const std::string d = describe_daemon_config(c);
  EXPECT_NE(d.find("configuration: config=" + file + " [flag --config]"), std::string::npos) << d;
}

TEST_F(DaemonConfigTest, FlagForms) {
  const LoadedConfig c = load({"--listen=127.0.0.1:7000", "--max-wall-time", "3600", "--listen",
                               "127.0.0.1:0", "--data-dir=/tmp/x=y"});
  EXPECT_EQ(c.config.listen, "127.0.0.1:0");  // repeated: the last wins
  EXPECT_DOUBLE_EQ(c.config.max_wall_time_s, 3600);
  EXPECT_EQ(c.config.data_dir, "/tmp/x=y");                           // only the first '=' splits
  EXPECT_TRUE(load({"--insecure-no-auth"}).config.insecure_no_auth);  // a switch
  EXPECT_FALSE(load({"--insecure-no-auth=false"}).config.insecure_no_auth);
  EXPECT_TRUE(load({"--help"}).help);
  EXPECT_TRUE(load({"--workers", "2", "--version"}).version);
}

TEST_F(DaemonConfigTest, EnvironmentNamesAndEmptyMeansUnset) {
  env_["SOFTSHOCK_DATA_DIR"] = "/var/lib/softshock";
  env_["SOFTSHOCK_TOKEN_FILE"] = "/run/secrets/t";
  env_["SOFTSHOCK_INSECURE_NO_AUTH"] = "yes";
  env_["SOFTSHOCK_MAX_END_TIME"] = "2e-6";
  env_["SOFTSHOCK_WORKERS"] = "";    // empty: as if unset
  env_["SOFTSHOCK_SERVER"] = "x:1";  // the client's variable: not a daemon setting, ignored
  const LoadedConfig c = load({});
  EXPECT_EQ(c.config.data_dir, "/var/lib/softshock");
  EXPECT_EQ(c.config.token_file, "/run/secrets/t");
  EXPECT_TRUE(c.config.insecure_no_auth);
  EXPECT_DOUBLE_EQ(c.config.max_end_time_s, 2e-6);
  EXPECT_EQ(c.config.workers, DaemonConfig().workers);
  EXPECT_EQ(c.source.count("workers"), 0u);
}

TEST_F(DaemonConfigTest, ConfigFileFromEnvironmentAndFlagOverridesIt) {
  const std::string a = write("a.conf", "workers = 2\n");
  const std::string b = write("b.conf", "workers = 9\n");
  env_["SOFTSHOCK_CONFIG"] = a;
  EXPECT_EQ(load({}).config.workers, 2);
  EXPECT_EQ(load({"--config", b}).config.workers, 9);
}

TEST_F(DaemonConfigTest, FileSyntax) {
  const std::string file = write("f.conf",
                                 "# softshockd settings\n"
                                 "\n"
                                 "  listen = \"127.0.0.1:9000\"   # loopback only\n"
                                 "data_dir = '/srv/soft # shock'\n"
                                 "token-file = \"/run/a \\\"b\\\"\"\n"
                                 "max_wall_time = 60 # a minute\n"
                                 "insecure-no-auth = false\n");
  const LoadedConfig c = load({"--config", file});
  EXPECT_EQ(c.config.listen, "127.0.0.1:9000");
  EXPECT_EQ(c.config.data_dir, "/srv/soft # shock");
  EXPECT_EQ(c.config.token_file, "/run/a \"b\"");
  EXPECT_DOUBLE_EQ(c.config.max_wall_time_s, 60);
  EXPECT_EQ(c.source.at("data-dir"), "file " + file + ":4");  // '_' and '-' are one key
}

TEST_F(DaemonConfigTest, InvalidValuesNameKeyAndSource) {
  const std::string file = write("bad.conf", "# comment\nworkers = 3\nmax-attempts = lots\n");
  std::string e = error_of({"--config", file});
  EXPECT_NE(e.find("max-attempts"), std::string::npos) << e;
  EXPECT_NE(e.find("'lots'"), std::string::npos) << e;
  EXPECT_NE(e.find("file " + file + ":3"), std::string::npos) << e;

  env_["SOFTSHOCK_WORKERS"] = "0";
  e = error_of({});
  EXPECT_NE(e.find("workers = '0' (env SOFTSHOCK_WORKERS)"), std::string::npos) << e;
  EXPECT_NE(e.find("1..4096"), std::string::npos) << e;
  // Checked although a flag overrides it: a broken variable is reported, not hidden.
  e = error_of({"--workers", "2"});
  EXPECT_NE(e.find("env SOFTSHOCK_WORKERS"), std::string::npos) << e;
  env_.clear();

  e = error_of({"--max-wall-time", "-1"});
  EXPECT_NE(e.find("max-wall-time = '-1' (flag --max-wall-time)"), std::string::npos) << e;
  for (const char* bad : {"nan", "inf", "1e400", "5s", ""}) {
    EXPECT_NE(error_of({std::string("--max-end-time=") + bad}).find("max-end-time"),
              std::string::npos)
        << bad;
  }
  EXPECT_NE(error_of({"--workers", "4x"}).find("flag --workers"), std::string::npos);
  EXPECT_NE(error_of({"--workers", "99999999999999999999"}).find("1..4096"), std::string::npos);
  EXPECT_NE(error_of({"--insecure-no-auth=maybe"}).find("true or false"), std::string::npos);
  EXPECT_NE(error_of({"--listen="}).find("non-empty"), std::string::npos);
}

TEST_F(DaemonConfigTest, MalformedFilesAndFlags) {
  auto file_error = [&](const std::string& text) {
    return error_of({"--config", write("m.conf", text)});
  };
  EXPECT_NE(file_error("wrkers = 2\n").find("m.conf:1: unknown key 'wrkers'"), std::string::npos);
  EXPECT_NE(file_error("workers = 2\nworkers = 3\n").find(":2: workers is already set at line 1"),
            std::string::npos);
  EXPECT_NE(file_error("[daemon]\n").find("sections are not supported"), std::string::npos);
  EXPECT_NE(file_error("workers 2\n").find("expected key = value"), std::string::npos);
  EXPECT_NE(file_error("listen = \"127.0.0.1:1\n").find("unterminated"), std::string::npos);
  EXPECT_NE(file_error("listen = \"a\" b\n").find("after the closing quote"), std::string::npos);
  EXPECT_NE(file_error("config = other.conf\n").find("cannot be set inside"), std::string::npos);

  const std::string missing = (dir_ / "none.conf").string();
  std::string e = error_of({"--config", missing});
  EXPECT_NE(e.find("cannot read config file " + missing + " (flag --config)"), std::string::npos)
      << e;
  env_["SOFTSHOCK_CONFIG"] = missing;
  EXPECT_NE(error_of({}).find("(env SOFTSHOCK_CONFIG)"), std::string::npos);
  env_.clear();

  EXPECT_NE(error_of({"--wokers", "2"}).find("unknown flag --wokers"), std::string::npos);
  EXPECT_NE(error_of({"--workers"}).find("--workers needs a value"), std::string::npos);
  EXPECT_NE(error_of({"workers"}).find("unexpected argument 'workers'"), std::string::npos);
}

TEST_F(DaemonConfigTest, TlsFilesGoTogether) {
  env_["SOFTSHOCK_TLS_CERT"] = "/etc/c.pem";
  const std::string e = error_of({});
  EXPECT_NE(e.find("tls-cert (env SOFTSHOCK_TLS_CERT) and tls-key (default) go together"),
            std::string::npos)
      << e;
  EXPECT_NO_THROW(load({"--tls-key", "/etc/k.pem"}));
}

TEST_F(DaemonConfigTest, RefusesExposedAddressWithoutToken) {
  for (const char* exposed : {"0.0.0.0:50051", "[::]:50051", ":50051", "10.1.2.3:50051",
                              "softshock.example.org:50051", "[::ffff:127.0.0.1]:1"}) {
    const std::string e = error_of({"--listen", exposed});
    EXPECT_NE(e.find("refusing to listen on " + std::string(exposed)), std::string::npos) << e;
    EXPECT_NE(e.find("[listen from flag --listen]"), std::string::npos) << e;
    EXPECT_NO_THROW(load({"--listen", exposed, "--token-file", "/run/t"})) << exposed;
    EXPECT_NO_THROW(load({"--listen", exposed, "--insecure-no-auth"})) << exposed;
  }
  env_["SOFTSHOCK_LISTEN"] = "0.0.0.0:50051";
  EXPECT_NE(error_of({}).find("[listen from env SOFTSHOCK_LISTEN]"), std::string::npos);
  // The token may come from another layer than the address.
  EXPECT_NO_THROW(load({"--config", write("t.conf", "token-file = /run/t\n")}));
  env_.clear();
  for (const char* local : {"127.0.0.1:50051", "127.0.0.1:0", "127.1.2.3:5", "localhost:50051",
                            "[::1]:50051", "unix:/run/softshock.sock"}) {
    EXPECT_NO_THROW(load({"--listen", local})) << local;
  }
  // The same rule guards a Daemon built in-process.
  DaemonConfig open;
  open.listen = "0.0.0.0:0";
  EXPECT_TRUE(exposure_problem(open).has_value());
  open.token_file = "/run/t";
  EXPECT_FALSE(exposure_problem(open).has_value());
}

TEST_F(DaemonConfigTest, TheDashboardPortFollowsTheSameExposureRule) {
  // The dashboard is the service over HTTP: off loopback it needs a token as --listen does.
  const std::string e = error_of({"--http-listen", "0.0.0.0:8080"});
  EXPECT_NE(e.find("refusing to serve the dashboard on 0.0.0.0:8080"), std::string::npos) << e;
  EXPECT_NE(e.find("[http-listen from flag --http-listen]"), std::string::npos) << e;
  EXPECT_NO_THROW(load({"--http-listen", "127.0.0.1:8080"}));
  EXPECT_NO_THROW(load({"--http-listen", "0.0.0.0:8080", "--token-file", "/run/t"}));
  // The metrics listener serves no job data: any address, no token needed.
  EXPECT_NO_THROW(load({"--metrics-listen", "0.0.0.0:9464"}));
  EXPECT_EQ(load({"--metrics-listen", "0.0.0.0:9464"}).config.metrics_listen, "0.0.0.0:9464");
  // A token sent in clear text to the dashboard off loopback is warned about.
  DaemonConfig c;
  c.token_file = "/run/t";
  EXPECT_FALSE(transport_warning(c).has_value());
  c.http_listen = "0.0.0.0:8080";
  const auto warning = transport_warning(c);
  ASSERT_TRUE(warning.has_value());
  EXPECT_NE(warning->find("serving the dashboard on 0.0.0.0:8080"), std::string::npos);
  c.tls_cert = "/etc/c.pem";
  c.tls_key = "/etc/k.pem";
  EXPECT_FALSE(transport_warning(c).has_value());
}

TEST_F(DaemonConfigTest, DescriptionShowsValuesAndSourcesButNoToken) {
  const std::string token_file = write("token", "s3cret-token-value\n");
  env_["SOFTSHOCK_TOKEN_FILE"] = token_file;
  const std::string d = describe_daemon_config(load({"--workers", "2"}));
  EXPECT_NE(d.find("workers=2 [flag --workers]"), std::string::npos) << d;
  EXPECT_NE(d.find("token-file=" + token_file + " [env SOFTSHOCK_TOKEN_FILE]"), std::string::npos)
      << d;
  EXPECT_NE(d.find("listen=127.0.0.1:50051 [default]"), std::string::npos) << d;
  EXPECT_NE(d.find("tls-cert=(none) [default]"), std::string::npos) << d;
  EXPECT_NE(d.find("config=(none) [default]"), std::string::npos) << d;
  EXPECT_EQ(d.find("s3cret"), std::string::npos) << d;
}

TEST_F(DaemonConfigTest, UsageDocumentsEveryLayer) {
  const std::string u = daemon_config_usage();
  for (const char* text :
       {"--config FILE", "SOFTSHOCK_CONFIG", "--workers N", "SOFTSHOCK_WORKERS",
        "--insecure-no-auth", "SOFTSHOCK_INSECURE_NO_AUTH", "SOFTSHOCK_TOKEN_FILE",
        "Precedence: flag > environment variable > config file > default", "key = value"}) {
    EXPECT_NE(u.find(text), std::string::npos) << text;
  }
}

}  // namespace
}  // namespace softshock::server
