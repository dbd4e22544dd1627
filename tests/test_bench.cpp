// `penumbra bench`: the quick sweep writes its CSV, summary and plots; its errors behave as the
// physics says (the path tracer's error falls about as 1/sqrt(samples), more work buys the final
// gather a lower error); its thread-scaling runs give identical results whatever the thread count;
// and bad input is refused before anything is written.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "bench/trade.h"
#include "fixtures.h"

using namespace penumbra;
namespace fs = std::filesystem;

namespace {

// trade.csv as one map of column name to text per row.
std::vector<std::map<std::string, std::string>> readCsv(const std::string& path) {
    std::ifstream in(path);
    std::string line;
    std::vector<std::string> header;
    std::vector<std::map<std::string, std::string>> rows;
    auto split = [](const std::string& l) {
        std::vector<std::string> cells;
        std::stringstream ss(l);
        std::string cell;
        while (std::getline(ss, cell, ',')) cells.push_back(cell);
        if (!l.empty() && l.back() == ',') cells.push_back("");
        return cells;
    };
    if (!std::getline(in, line)) return rows;
    header = split(line);
    while (std::getline(in, line)) {
        const auto cells = split(line);
        std::map<std::string, std::string> row;
        for (size_t k = 0; k < header.size() && k < cells.size(); ++k) row[header[k]] = cells[k];
        rows.push_back(row);
    }
    return rows;
}

bool isPng(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    char magic[8] = {};
    in.read(magic, 8);
    return in && std::string(magic + 1, 3) == "PNG" && fs::file_size(path) > 1000;
}

}  // namespace

TEST(BenchSlow, QuickSweepWritesTheTradeAndErrorFallsAsCostRises) {
    const std::string out = test::tempDir() + "/bench", cache = test::tempDir() + "/bench-cache";
    fs::remove_all(out);
    const test::CommandResult r = test::run(
        cat("bench ", PENUMBRA_SOURCE_DIR, "/scenes/cornell-box.json --out ", out, " --quick --cache ", cache));
    ASSERT_EQ(r.status, 0) << r.output;
    for (const char* file : {"trade.csv", "bench.json", "summary.md", "plots.gp"})
        EXPECT_TRUE(fs::exists(fs::path(out) / file)) << file;
    EXPECT_TRUE(isPng(out + "/error-time.png"));
    EXPECT_TRUE(isPng(out + "/cost-patches.png"));
    EXPECT_FALSE(fs::is_empty(cache)) << "the path-traced reference is not cached";

    const auto rows = readCsv(out + "/trade.csv");
    ASSERT_GE(rows.size(), 10u);
    std::vector<std::pair<double, double>> path, gather;  // (spp or seconds, error)
    for (const auto& row : rows) {
        const double error = std::stod(row.at("pooled_l1_blurred"));
        EXPECT_GT(error, 0.0);
        EXPECT_GT(std::stod(row.at("seconds_total")), 0.0);
        EXPECT_GT(std::stod(row.at("rays")), 0.0);
        if (row.at("method") == "path") path.emplace_back(std::stod(row.at("spp")), error);
        // (The ray-cast form factors' runs are another estimator, cheap and accurate at once: the
        // trade below is the analytic estimator's, coarse and fast against fine and slow.)
        if (row.at("method") == "final-gather" && row.at("form_factors") == "analytic")
            gather.emplace_back(std::stod(row.at("seconds_total")), error);
    }
    // Monte Carlo: 16 times the samples should divide the error by about 4; the reference's own
    // noise and the blur leave it well below 0.6 of the start.
    ASSERT_GE(path.size(), 3u);
    std::sort(path.begin(), path.end());
    for (size_t k = 1; k < path.size(); ++k) EXPECT_LT(path[k].second, path[k - 1].second) << "spp " << path[k].first;
    EXPECT_LT(path.back().second, 0.6 * path.front().second);
    // The costliest final gather (finest mesh) beats the cheapest (coarsest mesh, fewest samples).
    ASSERT_GE(gather.size(), 3u);
    std::sort(gather.begin(), gather.end());
    EXPECT_LT(gather.back().second, gather.front().second);

    std::ifstream jsonFile(out + "/bench.json");
    const nlohmann::json bench = nlohmann::json::parse(jsonFile);
    EXPECT_GT(bench["embree"]["occluded1_rays_per_s"].get<double>(), 1e5);
    EXPECT_GT(bench["bandwidth"]["read_gb_per_s"].get<double>(), 0.1);
    EXPECT_GT(bench["form_factors"]["rays_per_s"].get<double>(), 0.0);
    ASSERT_GE(bench["threads"].size(), 3u);
    for (const auto& stage : bench["threads"]) EXPECT_TRUE(stage["identical"].get<bool>()) << stage.dump();
}

TEST(Bench, RefusesASceneWithoutCameraBeforeWritingAnything) {
    const std::string scene = test::writeText("no-camera.json", R"({"materials": {
        "lamp": {"type": "diffuse", "reflectance": 0.5, "emission": 1}},
      "objects": [{"name": "light", "type": "quad", "material": "lamp", "vertices": [[0,0,0],[1,0,0],[1,1,0],[0,1,0]]}]})");
    const std::string out = test::tempDir() + "/bench-refused";
    fs::remove_all(out);
    const test::CommandResult r = test::run(cat("bench ", scene, " --out ", out, " --quick --cache ", out, "-cache"));
    EXPECT_EQ(r.status, 1) << r.output;
    EXPECT_NE(r.output.find("no-camera.json: camera"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(out));
    const test::CommandResult bad = test::run(cat("bench ", scene, " --out ", out, " --resolution 12by3"));
    EXPECT_EQ(bad.status, 1) << bad.output;
    EXPECT_NE(bad.output.find("--resolution"), std::string::npos) << bad.output;
    EXPECT_FALSE(fs::exists(out));
}

// The summary's transport row: each default solve's rays over its stage seconds, over Embree's
// nearest-hit rate, the median of the solves (and their range); none on a scene without mirrors.
TEST(Bench, TheTransportsRateIsItsRaysOverEmbreesNearestHitRate) {
    bench::BenchResult r;
    r.embree.intersect1 = 10e6;
    EXPECT_EQ(bench::transportRatio(r).runs, 0u);
    for (const auto& [rays, seconds] : std::vector<std::pair<double, double>>{{6e5, 0.1}, {6e5, 0.2}, {8e5, 0.1}}) {
        bench::ObjectRun o;
        o.transportRays = rays, o.transportSeconds = seconds;
        r.objectRuns.push_back(o);
    }
    r.objectRuns.push_back(bench::ObjectRun());  // a solve without a transport is left out
    const bench::StageRatio t = bench::transportRatio(r);
    EXPECT_EQ(t.runs, 3u);
    EXPECT_DOUBLE_EQ(t.median, 0.6);  // 6 M rays/s of 10
    EXPECT_DOUBLE_EQ(t.low, 0.3);
    EXPECT_DOUBLE_EQ(t.high, 0.8);
    EXPECT_DOUBLE_EQ(t.castRays / t.seconds, 6e6);
}
