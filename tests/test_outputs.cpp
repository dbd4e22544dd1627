// A run's outputs appear as one complete set or not at all, through the command line: whatever write
// or rename fails (injected: PENUMBRA_FAIL_AT), whenever SIGTERM arrives, whatever stands in the
// way, and whoever else writes into the same folder.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/file.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <thread>

#include "fixtures.h"

using namespace penumbra;
namespace fs = std::filesystem;

extern char** environ;

namespace {

using test::CommandResult;
using test::run;

const std::string kBox = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cornell-box.json";

// A small lit scene without a camera (a solve writes solution.bin, convergence.csv, report.json).
std::string smallScene() {
    return test::writeText("outputs-scene.json", R"({"materials": {
        "lamp": {"type": "diffuse", "reflectance": 0.5, "emission": 1},
        "white": {"type": "diffuse", "reflectance": 0.7}},
      "objects": [
        {"name": "light", "type": "quad", "material": "lamp", "vertices": [[0,1,0],[1,1,0],[1,1,1],[0,1,1]]},
        {"name": "floor", "type": "quad", "material": "white", "vertices": [[0,0,0],[0,0,1],[1,0,1],[1,0,0]]}]})");
}

// Every entry of a folder (hidden ones too) with its contents.
std::map<std::string, std::string> contents(const std::string& dir) {
    std::map<std::string, std::string> out;
    if (!fs::exists(dir)) return out;
    for (const auto& e : fs::directory_iterator(dir)) {
        std::stringstream text;
        if (e.is_regular_file()) text << std::ifstream(e.path(), std::ios::binary).rdbuf();
        out[e.path().filename().string()] = e.is_regular_file() ? text.str() : "<folder>";
    }
    return out;
}

size_t errorLines(const std::string& output) {
    size_t n = 0;
    for (size_t at = output.find("error:"); at != std::string::npos; at = output.find("error:", at + 1)) ++n;
    return n;
}

// Walks the injected failure over every write and rename of `command` (which writes into `dir`):
// each failing run exits non-zero with one error line and leaves `dir` as it found it; the walk
// ends at the first run no failure reaches, which must write the set `expected`. Returns how many
// writes and renames failed.
int walkFailures(const std::string& command, const std::string& dir, const std::set<std::string>& expected) {
    const std::map<std::string, std::string> before = contents(dir);
    const bool existed = fs::exists(dir);
    for (int n = 1; n < 100; ++n) {
        setenv("PENUMBRA_FAIL_AT", std::to_string(n).c_str(), 1);
        const CommandResult r = run(command);
        unsetenv("PENUMBRA_FAIL_AT");
        if (r.status == 0) {
            std::set<std::string> names;
            for (const auto& [name, text] : contents(dir)) names.insert(name);
            std::set<std::string> wanted = expected;
            for (const auto& [name, text] : before) wanted.insert(name);
            EXPECT_EQ(names, wanted) << "after the run no failure reached";
            return n - 1;
        }
        EXPECT_LT(r.status, 64) << "crashed at failure " << n << ": " << r.output;
        EXPECT_EQ(errorLines(r.output), 1u) << "failure " << n << ": " << r.output;
        EXPECT_NE(r.output.find("injected"), std::string::npos) << "failure " << n << ": " << r.output;
        EXPECT_EQ(fs::exists(dir), existed) << "failure " << n;
        EXPECT_EQ(contents(dir), before) << "failure " << n << " left the folder changed: " << r.output;
    }
    ADD_FAILURE() << "every run failed";
    return 0;
}

}  // namespace

TEST(Outputs, AFailedWriteOrRenameLeavesNoNewFolder) {
    const std::string out = test::tempDir() + "/fail-new";
    fs::remove_all(out);
    const int failures = walkFailures(cat("solve ", smallScene(), " --out ", out, " --patches 20 -q"), out,
                                      {"solution.bin", "convergence.csv", "report.json"});
    // Each of the three files: its write, its rename into the staging folder, its move into place.
    EXPECT_EQ(failures, 9);
}

TEST(Outputs, AFailedWriteOrRenameKeepsTheOlderSetWhole) {
    const std::string out = test::tempDir() + "/fail-older";
    fs::remove_all(out);
    ASSERT_EQ(run(cat("solve ", smallScene(), " --out ", out, " --patches 20 -q")).status, 0);
    std::ofstream(out + "/notes.txt") << "the user's own file";
    // Another mesh: every file of the new set differs from the older one's.
    const int failures = walkFailures(cat("solve ", smallScene(), " --out ", out, " --patches 40 -q"), out,
                                      {"solution.bin", "convergence.csv", "report.json"});
    EXPECT_EQ(failures, 12) << "moving each older file aside counts one more";
    EXPECT_EQ(contents(out).at("notes.txt"), "the user's own file");
}

TEST(Outputs, ARenderFailsWholeToo) {
    const std::string out = test::tempDir() + "/render-fail";
    fs::remove_all(out);
    fs::create_directories(out);
    const int failures =
        walkFailures(cat("render ", kBox, " --integrator path --spp 1 --resolution 16x12 --out ", out, "/box.exr -q"),
                     out, {"box.exr", "box.png"});
    EXPECT_EQ(failures, 6);
}

TEST(Outputs, AnExportAndAReferenceFailWholeToo) {
    // export and reference wrote straight to their file (tinygltf's and OpenMesh's writers unchecked):
    // now through the same output set, each format's write and its two moves.
    const std::string solved = test::tempDir() + "/export-solution";
    fs::remove_all(solved);
    ASSERT_EQ(run(cat("solve ", smallScene(), " --out ", solved, " --patches 20 -q")).status, 0);
    for (const std::string name : {"lit.glb", "lit.gltf", "lit.ply"}) {
        const std::string out = test::tempDir() + "/export-fail";
        fs::remove_all(out);
        EXPECT_EQ(walkFailures(cat("export ", solved, " --out ", out, "/", name, " -q"), out, {name}), 3) << name;
    }
    const std::string out = test::tempDir() + "/reference-fail";
    fs::remove_all(out);
    EXPECT_EQ(walkFailures(cat("reference ", smallScene(), " --out ", out,
                               "/reference.json --patches 20 --min-points 256 --max-points 256 -q"),
                           out, {"reference.json"}),
              3);
}

TEST(Outputs, AnOutputNameTakenByAFolderIsRefusedBeforeTheWork) {
    const std::string out = test::tempDir() + "/taken";
    fs::remove_all(out);
    fs::create_directories(out + "/report.json");
    const CommandResult r = run(cat("solve ", kBox, " --out ", out));
    EXPECT_NE(r.status, 0);
    EXPECT_EQ(errorLines(r.output), 1u) << r.output;
    EXPECT_NE(r.output.find(out + "/report.json: exists and is not a file"), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find("form factors"), std::string::npos) << "the work started: " << r.output;
    EXPECT_EQ(contents(out), (std::map<std::string, std::string>{{"report.json", "<folder>"}}));
}

TEST(Outputs, AnOutputFolderUnderAFileIsRefusedBeforeTheWork) {
    const std::string file = test::writeText("plain-file", "x");
    const CommandResult r = run(cat("solve ", kBox, " --out ", file, "/out"));
    EXPECT_NE(r.status, 0);
    EXPECT_EQ(errorLines(r.output), 1u) << r.output;
    EXPECT_NE(r.output.find(file + "/out"), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find("form factors"), std::string::npos) << "the work started: " << r.output;
    const CommandResult render = run(cat("render ", kBox, " --integrator path --out ", file, "/x.exr"));
    EXPECT_NE(render.status, 0);
    EXPECT_EQ(render.output.find("render counters"), std::string::npos) << "the work started: " << render.output;
}

TEST(Outputs, ASecondRunIntoAFolderBeingWrittenIsRefused) {
    // The lock another run holds (this test's, standing in for a solve in progress): two solves into
    // one folder mixed one's report with the other's solution, and both exited 0.
    const std::string out = test::tempDir() + "/locked";
    fs::remove_all(out);
    fs::create_directories(out);
    const int fd = ::open((out + "/.penumbra.lock").c_str(), O_RDWR | O_CREAT, 0644);
    ASSERT_GE(fd, 0);
    ASSERT_EQ(flock(fd, LOCK_EX | LOCK_NB), 0);
    const CommandResult r = run(cat("solve ", smallScene(), " --out ", out, " --patches 20"));
    EXPECT_NE(r.status, 0);
    EXPECT_EQ(errorLines(r.output), 1u) << r.output;
    EXPECT_NE(r.output.find("another penumbra run is writing"), std::string::npos) << r.output;
    EXPECT_EQ(contents(out), (std::map<std::string, std::string>{{".penumbra.lock", ""}})) << "the lock is not ours";
    ::close(fd);
}

TEST(Outputs, ALockFileReplacedBetweenOpenAndLockIsOpenedAgain) {
    // Run A removes its lock file as it ends; run B opened that file just before and locks it after;
    // run C made a new one and locked it: B and C would both write. Here the test is C: its locked
    // file takes the lock's name between B's open and B's flock (PENUMBRA_TEST_LOCK_SWAP). B must see
    // that the file it locked is no longer the one the name leads to, open the name again, and find
    // C's lock.
    const std::string out = test::tempDir() + "/swapped";
    fs::remove_all(out);
    fs::create_directories(out);
    const std::string third = out + "/third.lock";
    const int fd = ::open(third.c_str(), O_RDWR | O_CREAT, 0644);
    ASSERT_GE(fd, 0);
    ASSERT_EQ(flock(fd, LOCK_EX | LOCK_NB), 0);
    setenv("PENUMBRA_TEST_LOCK_SWAP", third.c_str(), 1);
    const CommandResult r = run(cat("solve ", smallScene(), " --out ", out, " --patches 20"));
    unsetenv("PENUMBRA_TEST_LOCK_SWAP");
    EXPECT_NE(r.status, 0) << r.output;
    EXPECT_EQ(errorLines(r.output), 1u) << r.output;
    EXPECT_NE(r.output.find("another penumbra run is writing"), std::string::npos) << r.output;
    EXPECT_EQ(contents(out), (std::map<std::string, std::string>{{".penumbra.lock", ""}}))
        << "C's lock, and nothing new";
    ::close(fd);
}

// SIGTERM at several moments of `command` (penumbra's arguments, OUT standing for a fresh folder
// under the test's, which the command writes into): the run exits with 128 + 15 and leaves OUT as
// it was (absent unless `made`, then empty), or it had finished and left `whole` there. Returns how
// many runs the signal stopped.
int stopAtMoments(const std::vector<std::string>& command, const std::set<std::string>& whole, bool made,
                  const std::string& name) {
    int stopped = 0;
    for (const int ms : {20, 60, 120, 200, 300, 450, 700}) {
        const std::string out = cat(test::tempDir(), "/term-", name, "-", ms);
        fs::remove_all(out);
        if (made) fs::create_directories(out);
        const std::string exe = PENUMBRA_EXE;
        std::vector<std::string> args{exe};
        for (const std::string& a : command)
            args.push_back(a == "OUT" ? out : a.rfind("OUT/", 0) == 0 ? out + a.substr(3) : a);
        std::vector<char*> argv;
        for (std::string& a : args) argv.push_back(a.data());
        argv.push_back(nullptr);
        pid_t pid = 0;
        EXPECT_EQ(posix_spawn(&pid, exe.c_str(), nullptr, nullptr, argv.data(), environ), 0);
        std::this_thread::sleep_for(std::chrono::milliseconds(ms));
        kill(pid, SIGTERM);
        int status = 0;
        EXPECT_EQ(waitpid(pid, &status, 0), pid);
        std::set<std::string> names;
        for (const auto& [entry, text] : contents(out)) names.insert(entry);
        if (WIFEXITED(status) && WEXITSTATUS(status) == 0) {
            EXPECT_EQ(names, whole) << name << " " << ms << " ms";
        } else {
            ++stopped;
            // Exit 143 from the handler; or, before it was installed (the first milliseconds of
            // loading), the signal's default action.
            EXPECT_TRUE((WIFEXITED(status) && WEXITSTATUS(status) == 128 + SIGTERM) ||
                        (WIFSIGNALED(status) && WTERMSIG(status) == SIGTERM))
                << name << " " << ms << " ms: status " << status;
            EXPECT_EQ(fs::exists(out), made) << name << " " << ms << " ms";
            EXPECT_TRUE(names.empty()) << name << " " << ms << " ms: left " << names.size() << " entries";
        }
    }
    return stopped;
}

TEST(Outputs, SigtermLeavesTheWholeSetOrNothing) {
    // A solve of the Cornell box (its work takes about 0.3 s) into a new folder.
    EXPECT_GT(stopAtMoments({"solve", kBox, "--out", "OUT", "-q"},
                            {"solution.bin", "convergence.csv", "report.json", "radiosity.exr", "radiosity.png"}, false,
                            "solve"),
              0)
        << "no solve was stopped: the test lost its case";
    // A default render (its own solve and the final gather, about 0.3 s) into an existing folder.
    EXPECT_GT(stopAtMoments({"render", kBox, "--out", "OUT/box.exr", "-q"}, {"box.exr", "box.png"}, true, "render"), 0)
        << "no render was stopped: the test lost its case";
}
