#pragma once
// What every `photorig` command reports, in one place: the exit codes that
// mean the same thing everywhere, and the result a command fills in, printed
// by main either as the command's own text or, with --json, as exactly one
// JSON document on stdout (docs/cli.md).
//
// Under --json main points the process's stdout at stderr before the command
// runs, so whatever a command prints for people (and spdlog, and progress)
// lands on stderr, and keeps the real stdout for the document alone. A
// command therefore prints its text as usual and adds its figures to
// ResultFields(); on failure it returns Fail(code, why).

#include <nlohmann/json.hpp>

#include <string>

namespace photorig::app {

enum ExitCode : int {
  kExitOk = 0,
  kExitFailed = 1,        // a failed run or solve: health checks, an unusable result, no usable signal
  kExitUsage = 2,         // bad flags, bad YAML, a missing file
  kExitUnavailable = 3,   // a device or the daemon cannot be reached or opened
  kExitInterrupted = 130  // SIGINT/SIGTERM, an aborted run
};

// True when --json was given to this process's command.
bool JsonOutput();

// The command's own fields of the JSON document ("command", "ok", "exit_code"
// and "error" are added by main).
nlohmann::json& ResultFields();

// Records `why` as the document's "error", prints "<command>: <why>" on
// stderr, and returns `code` for the command to return.
int Fail(ExitCode code, const std::string& why);

// Where a solve wrote its results: "results: DIR/" for people, and DIR as the
// "results_directory" of `fields` (the document's own, or one solve's part).
void ReportResultsDirectory(const std::string& directory, nlohmann::json& fields = ResultFields());

// Sends this process's text and JSON document to /dev/null: for the
// processes of a distributed solve (solve tomography --mpi) other than the
// first, which speaks for all of them.
void SilenceOutput();

namespace internal {
// Used by main only.
void BeginCommand(const std::string& name, bool json_output);
// Prints the document (under --json) on the saved stdout; returns `code`.
int EndCommand(int code, const std::string& error_if_unset);
const std::string& CommandName();
}  // namespace internal

}  // namespace photorig::app
