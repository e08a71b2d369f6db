#include "engine/spectra/line_sources.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "engine/spectra/test_data.h"

namespace qogi {
namespace {

using testing_util::HitranDir;
using testing_util::ScratchDir;

namespace fs = std::filesystem;

std::string Touch(const std::string& path) {
  fs::create_directories(fs::path(path).parent_path());
  std::ofstream(path) << "";
  return path;
}

std::string ErrorOf(const std::vector<std::string>& paths, const std::vector<std::string>& fallback,
                    const std::string& species = "CH4") {
  try {
    FindLineFiles(species, paths, fallback);
  } catch (const LineListNotFound& e) {
    return e.what();
  }
  return "";
}

// $QOGI_HITRAN_PATH set for one test, restored after it.
class HitranPathEnv {
 public:
  explicit HitranPathEnv(const std::string& value) {
    const char* old = std::getenv(kHitranPathVariable);
    had_ = old != nullptr;
    if (had_) old_ = old;
    if (value.empty())
      unsetenv(kHitranPathVariable);
    else
      setenv(kHitranPathVariable, value.c_str(), 1);
  }
  ~HitranPathEnv() {
    if (had_)
      setenv(kHitranPathVariable, old_.c_str(), 1);
    else
      unsetenv(kHitranPathVariable);
  }

 private:
  bool had_ = false;
  std::string old_;
};

TEST(LineSources, SpeciesFilesExactNameFirstThenPrefixedInNameOrder) {
  ScratchDir dir;
  const std::string d = dir.File("lines");
  const std::string b = Touch(d + "/ch4_b.data.gz");
  const std::string a = Touch(d + "/CH4-A.par");
  const std::string exact = Touch(d + "/CH4.par.gz");
  const std::string dot = Touch(d + "/CH4.hitran2020.par");
  Touch(d + "/CH4X.par");      // another name that merely starts with CH4
  Touch(d + "/CH4.txt");       // not a line-file extension
  Touch(d + "/CO2.par");       // another species
  fs::create_directories(d + "/CH4_dir.par");  // a folder, not a file
  EXPECT_EQ(SpeciesLineFiles(d, "CH4"), (std::vector<std::string>{exact, a, dot, b}));
  EXPECT_TRUE(SpeciesLineFiles(dir.File("absent"), "CH4").empty());
}

TEST(LineSources, NamedFilesAreUsedAsGivenAndFoldersSearchedInOrder) {
  HitranPathEnv env("");
  ScratchDir dir;
  const std::string user = dir.File("user"), other = dir.File("other");
  const std::string mine = Touch(user + "/CH4.par");
  const std::string theirs = Touch(other + "/CH4.par");
  const std::string single = Touch(dir.File("single/whatever.par"));
  // Files as given, folders beside them searched for the species.
  EXPECT_EQ(FindLineFiles("CH4", {single, user}, {other}),
            (std::vector<std::string>{single, mine}));
  // Only folders: the first that holds the species wins, the fallback last.
  EXPECT_EQ(FindLineFiles("CH4", {user}, {other}), std::vector<std::string>{mine});
  EXPECT_EQ(FindLineFiles("CH4", {}, {dir.File("empty"), other}), std::vector<std::string>{theirs});
  EXPECT_EQ(FindLineFiles("CH4", {}, {HitranDir()}),
            std::vector<std::string>{HitranDir() + "/CH4.par.gz"});
}

TEST(LineSources, EnvironmentFoldersComeAfterTheNamedOnesAndBeforeTheFallback) {
  ScratchDir dir;
  const std::string env_a = dir.File("env_a"), env_b = dir.File("env_b");
  const std::string in_b = Touch(env_b + "/CH4.par");
  HitranPathEnv env(env_a + ":" + env_b);
  EXPECT_EQ(LineSearchPath({"/named"}, {"/last"}),
            (std::vector<std::string>{"/named", env_a, env_b, "/last"}));
  EXPECT_EQ(FindLineFiles("CH4", {}, {HitranDir()}), std::vector<std::string>{in_b});
}

TEST(LineSources, MissingLineListsSayWhereTheyWereSoughtAndHowToProvideThem) {
  HitranPathEnv env("");
  ScratchDir dir;
  const std::string msg = ErrorOf({}, {dir.File("a"), dir.File("b")}, "NO2");
  EXPECT_NE(msg.find("no HITRAN line list for 'NO2'"), std::string::npos) << msg;
  EXPECT_NE(msg.find(dir.File("a") + ", " + dir.File("b")), std::string::npos) << msg;
  EXPECT_NE(msg.find("QOGI_HITRAN_PATH"), std::string::npos) << msg;
  EXPECT_NE(msg.find("qogi hitran fetch NO2"), std::string::npos) << msg;
  const std::string missing = ErrorOf({dir.File("nowhere.par")}, {HitranDir()});
  EXPECT_EQ(missing, "line list path not found: " + dir.File("nowhere.par"));
}

TEST(LineSources, FilesWithoutTheMoleculesLinesAreAnError) {
  const std::string co2 = HitranDir() + "/CO2.par.gz";
  EXPECT_EQ(ReadMoleculeLines({co2}, 2).molecule.front(), 2);
  try {
    ReadMoleculeLines({co2}, 6);
    FAIL() << "expected an error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("has no CH4 lines (molecule code 6)"), std::string::npos)
        << e.what();
  }
}

TEST(LineSources, LinesInMemoryWinAndAreNarrowedToTheSpecies) {
  LineSources sources;
  sources.fallback = {HitranDir()};
  const LineList both = MergeLineLists(
      {ReadLineFile(HitranDir() + "/CO2.par.gz"), ReadLineFile(HitranDir() + "/CH4.par.gz")});
  sources.lines["CH4"] = both;
  const LineList ch4 = LoadSpeciesLines("CH4", sources);
  const LineList from_file = ReadMoleculeLines({HitranDir() + "/CH4.par.gz"}, 6);
  EXPECT_EQ(ch4.nu_cm1, from_file.nu_cm1);
  EXPECT_EQ(LoadSpeciesLines("CO2", sources).size(),
            ReadLineFile(HitranDir() + "/CO2.par.gz").size());
  sources.lines["CO2"] = from_file;
  EXPECT_THROW(LoadSpeciesLines("CO2", sources), std::invalid_argument);
}

}  // namespace
}  // namespace qogi
