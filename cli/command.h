// The `waymark` binary's subcommands. Each lives in one file, cli/cmd_<name>.cc, and
// registers itself with a static CommandRegistrar; main.cc dispatches on argv[1].
// Commands do no math: they parse arguments, call the libraries and report.
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace waymark::cli {

struct Command {
  std::string name;     // e.g. "sim", "dataset", "eval"
  std::string summary;  // one line for `waymark help`
  std::string usage;    // full text for `waymark <name> --help`
  // Arguments after the command name. Returns the process exit code; throws
  // std::exception for errors (main prints the message as one line and exits 1).
  std::function<int(const std::vector<std::string>& args)> run;
};

const std::vector<Command>& AllCommands();
const Command* FindCommand(const std::string& name);

struct CommandRegistrar {
  explicit CommandRegistrar(Command command);
};

// True when stderr is a terminal: progress is shown there and nowhere else.
bool StderrIsTerminal();

}  // namespace waymark::cli
