// The `waymark` binary's subcommands. Each lives in one file, cli/cmd_<name>.cc, and
// registers itself with a static CommandRegistrar; main.cc dispatches on argv[1].
// Commands do no math: they parse arguments, call the libraries and report.
#pragma once

#include <functional>
#include <string>
#include <vector>

namespace waymark::cli {

struct Command {
  // e.g. "sim", "dataset", "eval"; "<command> <verb>" (e.g. "map score") for a verb that lives in
  // a file of its own: main.cc tries "<argv[1]> <argv[2]>" before "<argv[1]>".
  std::string name;
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
