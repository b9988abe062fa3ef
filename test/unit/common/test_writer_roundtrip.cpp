// Round-trip properties of the writers: whatever a writer writes, the matching
// reader gives back exactly (bit for bit), and writing what was read gives the same bytes.
// Over many generated inputs, not hand-picked examples.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <map>

#include "ddace/common/file.h"
#include "ddace/common/random.h"
#include "ddace/gp/primitives.h"
#include "ddace/task/task_dir.h"
#include "ddace/tasks/generators.h"

using namespace ddace;
namespace fs = std::filesystem;

namespace {

std::string tempDir(const std::string& name) {
  const std::string dir = ::testing::TempDir() + "/ddace_roundtrip_" + std::to_string(::getpid()) + "/" + name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

std::string randomBytes(SplitMix64& rng, size_t n) {
  std::string s(n, '\0');
  for (auto& c : s) {
    // Mostly the bytes that matter to text handling (NUL, CR, LF, 0xFF), else any byte.
    static const char special[] = {'\0', '\r', '\n', '\xff', ','};
    c = rng.uniform() < 0.2 ? special[rng.index(sizeof special)] : static_cast<char>(rng.next() & 0xff);
  }
  return s;
}

/// Bit-identical doubles (EXPECT_EQ would take -0.0 == 0.0).
bool sameBits(double a, double b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

}  // namespace

TEST(WriterRoundTrip, TextFilesReadBackByteForByteWhateverTheirSizeAndBytes) {
  const std::string dir = tempDir("text");
  SplitMix64 rng(0x7e57f11e);
  const std::string path = dir + "/file.bin";
  // Sizes around the readers' and writers' 64 KiB buffers, and random ones; each write
  // replaces a file of another size (a shorter content leaves no tail of the old one).
  std::vector<size_t> sizes = {0, 1, 2, 65535, 65536, 65537, 131072, (1u << 20) + 3};
  for (int i = 0; i < 24; ++i) sizes.push_back(rng.index(300000));
  for (size_t n : sizes) {
    const std::string bytes = randomBytes(rng, n);
    writeTextFile(path, bytes);
    ASSERT_EQ(readTextFile(path), bytes) << n << " bytes";
    // The same through OutputFile in random pieces, and InputFile as a stream.
    {
      OutputFile out(path);
      for (size_t at = 0; at < n;) {
        const size_t piece = std::min(n - at, 1 + rng.index(70000));
        out.stream().write(bytes.data() + at, static_cast<std::streamsize>(piece));
        at += piece;
      }
      out.commit();
    }
    InputFile in(path);
    std::string streamed((std::istreambuf_iterator<char>(in.stream())), {});
    ASSERT_EQ(streamed, bytes) << n << " bytes, streamed";
    EXPECT_FALSE(in.exceeded());
  }
  // Nothing but the file itself is left in the directory (no temporary).
  size_t entries = 0;
  for (const auto& e : fs::directory_iterator(dir)) entries += e.path().filename() == "file.bin" ? 0 : 1;
  EXPECT_EQ(entries, 0u);
}

TEST(WriterRoundTrip, TaskDirectoriesOfEveryFamilyReadBackExactly) {
  // Every family, several seeds, with position noise (arbitrary digits), mislabels and
  // human-timed onsets: writeTaskDir -> loadTaskDir gives the same spec, times, positions
  // and labels bit for bit, the same steps, and writing again the same bytes.
  const std::string root = tempDir("taskdir");
  int checked = 0;
  for (const std::string& family : tasks::allFamilies()) {
    for (uint64_t seed : {1, 7, 1234567}) {
      tasks::GeneratorOptions o;
      o.family = family;
      o.demos = 3;
      o.seed = seed;
      o.jitter_m = seed == 7 ? 0.0 : 0.003;
      o.mislabel_fraction = seed == 1234567 ? 0.5 : 0.0;
      o.onset_jitter_s = seed == 7 ? 0.2 : 0.0;
      if (family == "task2") o.robots = 4 + static_cast<int>(seed % 8);
      if (family == "task3") o.actions = 2 + static_cast<int>(seed % 3);
      const task::TaskDir a = tasks::generate(o);
      const std::string dir = root + "/" + family + "_" + std::to_string(seed);
      task::writeTaskDir(a, dir);
      const task::TaskDir b = task::loadTaskDir(dir);
      EXPECT_EQ(task::taskYamlText(b.spec), task::taskYamlText(a.spec)) << dir;
      ASSERT_EQ(b.demos.size(), a.demos.size()) << dir;
      for (size_t d = 0; d < a.demos.size(); ++d) {
        const task::Demonstration &x = a.demos[d], &y = b.demos[d];
        ASSERT_EQ(y.rows(), x.rows()) << dir << " demo " << d;
        for (size_t r = 0; r < x.rows(); ++r) {
          ASSERT_TRUE(sameBits(y.t[r], x.t[r])) << dir << " demo " << d << " row " << r;
          for (size_t e = 0; e < x.entities(); ++e) {
            ASSERT_TRUE(sameBits(y.positions[r][e].x(), x.positions[r][e].x())) << dir << " row " << r;
            ASSERT_TRUE(sameBits(y.positions[r][e].y(), x.positions[r][e].y())) << dir << " row " << r;
          }
        }
        EXPECT_EQ(y.labels, x.labels) << dir << " demo " << d;
        EXPECT_EQ(y.keyframes, x.keyframes) << dir << " demo " << d;
        ASSERT_EQ(y.segments.size(), x.segments.size()) << dir << " demo " << d;
        for (size_t s = 0; s < x.segments.size(); ++s) EXPECT_EQ(y.segments[s].token, x.segments[s].token);
      }
      const auto again = task::taskDirFiles(b), first = task::taskDirFiles(a);
      EXPECT_EQ(again, first) << dir;
      ++checked;
    }
  }
  EXPECT_EQ(checked, static_cast<int>(tasks::allFamilies().size()) * 3);
}

TEST(WriterRoundTrip, PrimitiveLibrariesReadBackToTheSamePathsAndTheSameBytes) {
  const std::string dir = tempDir("primitives");
  for (const std::string& family : tasks::paperFamilies()) {
    tasks::GeneratorOptions o;
    o.family = family;
    o.demos = 4;
    o.jitter_m = 0.002;
    if (family == "task2") o.robots = 4;
    const gp::PrimitiveLibrary a = gp::PrimitiveLibrary::fit(tasks::generate(o));
    const std::string first = dir + "/" + family + ".yaml", second = dir + "/" + family + "_again.yaml";
    a.save(first);
    const gp::PrimitiveLibrary b = gp::PrimitiveLibrary::load(first);
    b.save(second);
    EXPECT_EQ(readTextFile(second), readTextFile(first)) << family;
    ASSERT_EQ(b.primitives().size(), a.primitives().size()) << family;
    SplitMix64 rng(0x9a7d);
    for (const auto& [key, p] : a.primitives()) {
      const Eigen::Vector2d start(rng.uniform(), rng.uniform()), goal(rng.uniform(), rng.uniform());
      const int n = 2 + static_cast<int>(rng.index(150));
      const auto pa = a.generate(key, start, goal, n), pb = b.generate(key, start, goal, n);
      ASSERT_EQ(pb.points.size(), pa.points.size()) << key;
      for (size_t i = 0; i < pa.points.size(); ++i) {
        EXPECT_TRUE(sameBits(pb.points[i].x(), pa.points[i].x())) << family << " " << key << " point " << i;
        EXPECT_TRUE(sameBits(pb.points[i].y(), pa.points[i].y())) << family << " " << key << " point " << i;
        EXPECT_TRUE(sameBits(pb.stddev[i], pa.stddev[i])) << family << " " << key << " point " << i;
      }
    }
  }
}
