// The same command under mpirun (Open MPI, on this machine's loopback) as in one process: images
// identical bit for bit, the solve's files too, and a rank that dies ends the job with a message
// naming it and no output left (docs/distributed.md).
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "fixtures.h"

namespace fs = std::filesystem;
using namespace penumbra;
using test::CommandResult;
using test::run;

namespace {

// `penumbra ARGS` under `mpirun -np RANKS` (oversubscribed: this machine has two cores). Root may run
// it (Open MPI asks for both variables); the sanitizers' leak check is off, as MPI's own start-up
// allocations are not ours to free.
CommandResult runRanks(int ranks, const std::string& args, const std::string& env = "") {
    return run(args, cat("OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 ", "ASAN_OPTIONS=detect_leaks=0 ",
                         env, " ", PENUMBRA_MPIEXEC, " --oversubscribe -np ", ranks, " "));
}

std::string bytesOf(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

std::string sceneFile(const std::string& name) { return cat(PENUMBRA_SOURCE_DIR, "/scenes/", name); }

}  // namespace

// Every integrator's image, and an orbit's, from 2 and 3 ranks equal to one process's, byte for byte:
// rows dealt out to the ranks, the solve (made by rank 0) and the caustic photons and light paths
// (traced in chunks by all) shared.
TEST(Cluster, RendersUnderMpirunEqualOneProcessBitForBit) {
    const std::string out = test::tempDir() + "/cluster-render";
    fs::remove_all(out);
    fs::create_directories(out);
    struct Case {
        std::string name, args;
        std::vector<std::string> files;
    };
    const std::string small = " --resolution 48x40 --quiet";
    const std::vector<Case> cases{
        {"gather",
         sceneFile("cornell-glass.json") + " --spp 4 --patches 300 --form-factors rays" + small,
         {".exr", ".png"}},
        {"path", sceneFile("cornell-glass.json") + " --integrator path --spp 8" + small, {".exr"}},
        {"orbit",
         sceneFile("cornell-box.json") + " --integrator radiosity --orbit 2 --patches 300 --form-factors rays" + small,
         {"-000.exr", "-001.exr", "-orbit.json"}},
    };
    for (const Case& c : cases) {
        const CommandResult one = run(cat("render ", c.args, " --out ", out, "/", c.name, "-1.exr"));
        ASSERT_EQ(one.status, 0) << one.output;
        for (int ranks : {2, 3}) {
            const CommandResult many =
                runRanks(ranks, cat("render ", c.args, " --out ", out, "/", c.name, "-", ranks, ".exr"));
            ASSERT_EQ(many.status, 0) << many.output;
            for (const std::string& f : c.files) {
                const std::string a = bytesOf(cat(out, "/", c.name, "-1", f)),
                                  b = bytesOf(cat(out, "/", c.name, "-", ranks, f));
                ASSERT_FALSE(a.empty()) << c.name << f;
                if (f == "-orbit.json") continue;  // names the files, which differ
                EXPECT_TRUE(a == b) << c.name << f << " from " << ranks << " ranks differs from one process's";
            }
        }
    }
}

TEST(Cluster, SolveUnderMpirunWritesTheOneProcessSolution) {
    const std::string out = test::tempDir() + "/cluster-solve";
    fs::remove_all(out);
    const std::string args = sceneFile("cornell-box.json") + " --patches 300 --form-factors rays --quiet";
    ASSERT_EQ(run(cat("solve ", args, " --out ", out, "/one")).status, 0);
    const CommandResult many = runRanks(2, cat("solve ", args, " --out ", out, "/two"));
    ASSERT_EQ(many.status, 0) << many.output;
    EXPECT_EQ(bytesOf(out + "/one/solution.bin"), bytesOf(out + "/two/solution.bin"));
    EXPECT_EQ(bytesOf(out + "/one/radiosity.exr"), bytesOf(out + "/two/radiosity.exr"));
}

// A rank that dies (SIGKILL, as a crash or a lost host would end it: PENUMBRA_TEST_KILL_RANK) stops
// the others within seconds; the run exits non-zero, mpirun's message names the rank and its host,
// and nothing is left in the output folder, which the run made.
TEST(Cluster, ARankKilledStopsTheJobAndLeavesNoOutput) {
    const std::string out = test::tempDir() + "/cluster-kill";
    fs::remove_all(out);
    for (const std::string& command :
         {cat("solve ", sceneFile("cornell-box.json"), " --patches 300 --form-factors rays --out ", out, "/solve"),
          cat("render ", sceneFile("cornell-glass.json"),
              " --resolution 48x40 --spp 4 --patches 300 --form-factors rays --out ", out, "/render/image.exr")}) {
        const auto start = std::chrono::steady_clock::now();
        const CommandResult r = runRanks(2, command, "PENUMBRA_TEST_KILL_RANK=1");
        const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        EXPECT_NE(r.status, 0) << r.output;
        EXPECT_NE(r.output.find("rank 1"), std::string::npos) << r.output;
        EXPECT_NE(r.output.find("signal 9"), std::string::npos) << r.output;
        EXPECT_LT(seconds, 30) << r.output;
    }
    EXPECT_FALSE(fs::exists(out + "/solve")) << "the solve's folder is left";
    EXPECT_FALSE(fs::exists(out + "/render")) << "the render's folder is left";
}
