// The CLI's help as a user reads it, checked against the binary itself: every command and option
// that `strut ... --help` lists is in the README, option help is whole sentences, numeric ranges
// print readably, and an out-of-range value is refused naming the option and the range.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "strut/ident/model.h"
#include "strut_cli.h"

namespace strut {
namespace {

std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

std::string Trim(const std::string& s) {
  const auto b = s.find_first_not_of(' ');
  return b == std::string::npos ? std::string() : s.substr(b, s.find_last_not_of(' ') - b + 1);
}

// One option as CLI11 lists it: its names ("-o,--output") and its description.
struct HelpOption {
  std::string names;
  std::string description;
  std::string long_name() const {
    const auto comma = names.rfind(',');
    return comma == std::string::npos ? names : names.substr(comma + 1);
  }
};

// One command's help: its options and its subcommands. CLI11 2.1 puts an entry's description at
// column 30, or on the next line when the entry is wider.
struct Help {
  std::string text;
  std::vector<HelpOption> options;
  std::vector<std::string> subcommands;
};

Help ReadHelp(const std::string& command) {
  const auto r = test::RunStrut(command + " --help");
  EXPECT_EQ(r.exit_code, 0) << command << ": " << r.output;
  Help help{r.output, {}, {}};
  const std::vector<std::string> lines = Lines(r.output);
  std::string section;
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const std::string& line = lines[i];
    if (!line.empty() && line[0] != ' ') {
      section = line;
      continue;
    }
    if (line.rfind("  ", 0) != 0 || line.size() < 3 || line[2] == ' ') continue;  // not an entry
    // An entry of 30 characters or more has its description on the next line, indented by 30.
    const bool next_line = i + 1 < lines.size() && lines[i + 1].rfind(std::string(30, ' '), 0) == 0;
    const std::string head = next_line || line.size() <= 30 ? line : line.substr(0, 30);
    const std::string description = next_line ? Trim(lines[i + 1]) : Trim(line.substr(head.size()));
    const std::string name = Trim(head).substr(0, Trim(head).find(' '));
    if (section == "Subcommands:") help.subcommands.push_back(name);
    if (section == "Options:") help.options.push_back({name, description});
  }
  return help;
}

// Every command path below `strut`, e.g. "sim matrix", "bench units", with its help.
void Walk(const std::string& path, std::vector<std::pair<std::string, Help>>& out) {
  Help help = ReadHelp(path.empty() ? std::string() : path);
  const std::vector<std::string> subcommands = help.subcommands;
  out.emplace_back(path, std::move(help));
  for (const std::string& sub : subcommands) Walk(path.empty() ? sub : path + " " + sub, out);
}

const std::vector<std::pair<std::string, Help>>& AllCommands() {
  static const auto* commands = [] {
    auto* v = new std::vector<std::pair<std::string, Help>>;
    Walk("", *v);
    return v;
  }();
  return *commands;
}

// The README's CLI section, and the entry of one command in it: from the line "    strut PATH"
// to the next line that starts another command.
std::string ReadmeCliSection() {
  const std::string readme = test::ReadFile(std::string(STRUT_SOURCE_DIR) + "/README.md");
  const auto begin = readme.find("## The CLI");
  EXPECT_NE(begin, std::string::npos);
  return readme.substr(begin, readme.find("\n## ", begin + 1) - begin);
}

std::string ReadmeEntry(const std::string& section, const std::string& path) {
  std::string entry;
  bool inside = false;
  for (const std::string& line : Lines(section)) {
    const bool starts_command = line.rfind("    strut ", 0) == 0;
    if (starts_command) inside = line == "    strut " + path || line.rfind("    strut " + path + " ", 0) == 0;
    if (inside) entry += line + "\n";
  }
  return entry;
}

TEST(CliHelp, TheWalkFindsEveryCommand) {
  std::vector<std::string> paths;
  for (const auto& [path, help] : AllCommands()) paths.push_back(path);
  for (const char* expected : {"info", "periodic", "identify", "discover", "demo", "sim matrix", "sim drop",
                               "sim truth", "import csv", "import mat", "bench periodic", "bench identify",
                               "bench units", "bench discover", "bench confusion", "bench sim", "bench silverbox"})
    EXPECT_NE(std::find(paths.begin(), paths.end(), expected), paths.end()) << expected;
  for (const auto& [path, help] : AllCommands())
    if (path == "sim drop") {
      ASSERT_GE(help.options.size(), 5u);
      bool mass = false;
      for (const auto& o : help.options)
        mass = mass || (o.long_name() == "--mass" && o.description == "The dropped mass in kg.");
      EXPECT_TRUE(mass) << help.text;
    }
}

TEST(CliHelp, ReadmeListsEveryCommandAndOption) {
  const std::string section = ReadmeCliSection();
  for (const auto& [path, help] : AllCommands()) {
    if (path.empty()) {  // the options of strut itself
      for (const auto& o : help.options)
        if (o.long_name() != "--help") EXPECT_NE(section.find(o.long_name()), std::string::npos) << o.names;
      continue;
    }
    if (!help.subcommands.empty()) continue;  // "sim", "bench", "import": their subcommands are the commands
    const std::string entry = ReadmeEntry(section, path);
    EXPECT_FALSE(entry.empty()) << "README.md has no line '    strut " << path << " ...'";
    for (const auto& o : help.options)
      if (o.long_name() != "--help")
        EXPECT_NE(entry.find(o.long_name()), std::string::npos)
            << "README.md, strut " << path << ": " << o.long_name() << " is missing from\n"
            << entry;
  }
}

TEST(CliHelp, ReadmeNamesEveryDoc) {
  const std::string readme = test::ReadFile(std::string(STRUT_SOURCE_DIR) + "/README.md");
  int docs = 0;
  for (const auto& entry : std::filesystem::directory_iterator(std::string(STRUT_SOURCE_DIR) + "/docs")) {
    if (entry.path().extension() != ".md") continue;
    ++docs;
    EXPECT_NE(readme.find("docs/" + entry.path().filename().string()), std::string::npos) << entry.path();
  }
  EXPECT_GE(docs, 10);
}

TEST(CliHelp, OptionHelpIsWholeSentences) {
  for (const auto& [path, help] : AllCommands())
    for (const auto& o : help.options) {
      if (o.long_name() == "--help" || o.long_name() == "--version") continue;  // CLI11's own
      ASSERT_FALSE(o.description.empty()) << path << " " << o.names;
      EXPECT_TRUE(std::isupper(static_cast<unsigned char>(o.description.front())))
          << "strut " << path << " " << o.names << ": " << o.description;
      EXPECT_EQ(o.description.back(), '.') << "strut " << path << " " << o.names << ": " << o.description;
    }
}

TEST(CliHelp, EveryCommandThatTakesAModelTakesSetAndParams) {
  for (const char* path : {"periodic", "identify", "discover"}) {
    const Help help = ReadHelp(path);
    std::vector<std::string> names;
    for (const auto& o : help.options) names.push_back(o.long_name());
    for (const char* option : {"--model", "--input", "--set", "--params"})
      EXPECT_NE(std::find(names.begin(), names.end(), option), names.end()) << path << " lacks " << option;
    // --model names every base and term of the catalogue.
    for (const auto& o : help.options)
      if (o.long_name() == "--model")
        for (const std::string& name : ident::Model::Catalogue())
          EXPECT_NE(o.description.find(name), std::string::npos) << path << " --model: " << name;
  }
  // The options are read, not only listed: a --set of a name no model has is refused by name.
  const auto r = test::RunStrut("discover " + std::string(STRUT_SOURCE_DIR) + "/README.md --set theta999=1");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(r.output.find("File does not exist"), std::string::npos) << r.output;
}

TEST(CliHelp, NumericRangesPrintReadably) {
  const std::regex long_number("[0-9]{13,}");
  for (const auto& [path, help] : AllCommands())
    EXPECT_FALSE(std::regex_search(help.text, long_number)) << "strut " << path << " --help:\n" << help.text;
  const Help drop = ReadHelp("sim drop");
  EXPECT_NE(drop.text.find("--mass FLOAT:> 0 kg (default 350)"), std::string::npos) << drop.text;
  EXPECT_NE(drop.text.find("--velocity FLOAT:>= 0 m/s (default 0.5)"), std::string::npos) << drop.text;
  EXPECT_NE(drop.text.find("--duration FLOAT:0.001 .. 3600 s (default 30)"), std::string::npos) << drop.text;
  EXPECT_NE(ReadHelp("identify").text.find("--n INT:16 .. 100000 "), std::string::npos);
}

TEST(CliHelp, AnOutOfRangeValueIsRefusedNamingTheOptionAndTheRange) {
  test::TempDir dir;
  const std::string file = std::string(STRUT_SOURCE_DIR) + "/README.md";  // any existing file
  struct Case {
    std::string args, message;
  };
  for (const Case& c : std::vector<Case>{
           {"sim drop --mass 0 -o " + dir.file("d.h5"), "--mass: 0 is out of range; give a number > 0 kg"},
           {"sim drop --mass -3 -o " + dir.file("d.h5"), "--mass: -3 is out of range; give a number > 0 kg"},
           {"sim drop --mass heavy -o " + dir.file("d.h5"), "--mass: 'heavy' is not a number; give a number > 0 kg"},
           {"sim drop --velocity -0.1 -o " + dir.file("d.h5"),
            "--velocity: -0.1 is out of range; give a number >= 0 m/s"},
           {"sim matrix --real-time --speed 0 -o " + dir.file("m.h5"), "--speed: 0 is out of range; give a number > 0"},
           {"identify " + file + " --n 3", "--n: 3 is out of range; give a number 16 .. 100000"},
           {"discover " + file + " --threads 0", "--threads: 0 is out of range; give a number 1 .. 64"},
           {"periodic --frequency 0 --amplitude 0.01 --static 0.1",
            "--frequency: 0 is out of range; give a number > 0 Hz"},
           {"import csv " + file + " --gzip 10 -o " + dir.file("i.h5"),
            "--gzip: 10 is out of range; give a number 0 .. 9"},
           {"bench units --start-off 1", "--start-off: 1 is out of range; give a number 0 .. 0.9"},
       }) {
    const auto r = test::RunStrut(c.args);
    EXPECT_EQ(r.exit_code, 1) << c.args << "\n" << r.output;
    EXPECT_NE(r.output.find(c.message), std::string::npos) << c.args << "\n" << r.output;
  }
  EXPECT_FALSE(std::filesystem::exists(dir.file("d.h5")));
}

TEST(CliHelp, ExitCodesOfHelpAndOfRefusedCommandLines) {
  EXPECT_EQ(test::RunStrut("--help").exit_code, 0);
  EXPECT_EQ(test::RunStrut("--version").exit_code, 0);
  EXPECT_EQ(test::RunStrut("").exit_code, 1);  // a command is required
  EXPECT_EQ(test::RunStrut("no-such-command").exit_code, 1);
  EXPECT_EQ(test::RunStrut("sim drop").exit_code, 1);  // -o is required
}

}  // namespace
}  // namespace strut
