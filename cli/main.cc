// waymark: maps and localization from printed codes. Dispatches to the subcommands
// registered in cli/cmd_*.cc; prints one line to stderr and exits non-zero on error.
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <exception>
#include <iostream>
#include <string>
#include <vector>

#include "cli/command.h"

namespace waymark::cli {
namespace {

std::vector<Command>& Registry() {
  static std::vector<Command> commands;
  return commands;
}

void PrintHelp(std::ostream& out) {
  out << "waymark: maps and robot localization from printed codes (QR, DataMatrix, AprilTag)\n\n"
         "Usage: waymark <command> [options]\n\nCommands:\n";
  std::vector<Command> commands = AllCommands();
  std::sort(commands.begin(), commands.end(),
            [](const Command& a, const Command& b) { return a.name < b.name; });
  for (const Command& c : commands) {
    out << "  " << c.name << std::string(c.name.size() < 12 ? 12 - c.name.size() : 1, ' ') << c.summary
        << "\n";
  }
  out << "  help        this list\n\nRun `waymark <command> --help` for a command's options.\n";
}

}  // namespace

const std::vector<Command>& AllCommands() { return Registry(); }

const Command* FindCommand(const std::string& name) {
  for (const Command& c : Registry()) {
    if (c.name == name) return &c;
  }
  return nullptr;
}

CommandRegistrar::CommandRegistrar(Command command) { Registry().push_back(std::move(command)); }

bool StderrIsTerminal() { return isatty(STDERR_FILENO) == 1; }

}  // namespace waymark::cli

int main(int argc, char** argv) {
  using waymark::cli::FindCommand;
  std::vector<std::string> args(argv + 1, argv + argc);
  if (args.empty() || args[0] == "help" || args[0] == "--help" || args[0] == "-h") {
    if (args.size() >= 2) {
      std::string name = args[1];
      for (size_t i = 2; i < args.size(); ++i) name += " " + args[i];
      if (const auto* command = FindCommand(name)) {
        std::cout << command->usage;
        return 0;
      }
    }
    waymark::cli::PrintHelp(args.empty() ? std::cerr : std::cout);
    return args.empty() ? 2 : 0;
  }
  // A verb may be a command of its own, registered as "<command> <verb>" (e.g. "map score").
  size_t used = 1;
  const waymark::cli::Command* command = nullptr;
  if (args.size() >= 2) command = FindCommand(args[0] + " " + args[1]);
  if (command != nullptr) {
    used = 2;
  } else {
    command = FindCommand(args[0]);
  }
  if (command == nullptr) {
    std::cerr << "Command `" << args[0] << "` not recognized. Run `waymark help`.\n";
    return 2;
  }
  const std::vector<std::string> rest(args.begin() + used, args.end());
  if (!rest.empty() && (rest[0] == "--help" || rest[0] == "-h")) {
    std::cout << command->usage;
    return 0;
  }
  // Other --help positions (after a verb, e.g. `waymark dataset info --help`) are the
  // command's to handle.
  try {
    return command->run(rest);
  } catch (const std::exception& e) {
    std::cerr << "waymark " << command->name << ": error: " << e.what() << "\n";
    return 1;
  }
}
