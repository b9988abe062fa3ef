// Reading only regular files of bounded size; checked, atomic writes.
#include <gtest/gtest.h>
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <future>
#include <string>
#include <vector>

#include "ddace/common/error.h"
#include "ddace/common/file.h"

#include "error_of.h"

namespace fs = std::filesystem;
using ddace::readTextFile;
using ddace::writeTextFile;
using ddace::test::errorOf;

namespace {

// A fresh directory, removed with everything in it at the end of the test.
class TempDir {
 public:
  TempDir() {
    std::string pattern = (fs::temp_directory_path() / "ddace_file_test_XXXXXX").string();
    if (::mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
    path_ = pattern;
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  std::string file(const std::string& name) const { return (path_ / name).string(); }
  std::vector<std::string> entries() const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(path_)) names.push_back(e.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
  }

 private:
  fs::path path_;
};

}  // namespace

TEST(ReadTextFile, ReadsTheWholeFile) {
  TempDir dir;
  const std::string bytes("line 1\nline 2\0binary\r\n", 22);
  writeTextFile(dir.file("a.txt"), bytes);
  EXPECT_EQ(readTextFile(dir.file("a.txt")), bytes);
}

TEST(ReadTextFile, MissingFileNamesTheFile) {
  TempDir dir;
  const std::string message = errorOf([&] { readTextFile(dir.file("missing.yaml")); });
  EXPECT_NE(message.find(dir.file("missing.yaml")), std::string::npos) << message;
  EXPECT_NE(message.find("No such file"), std::string::npos) << message;
}

TEST(ReadTextFile, FifoIsRefusedWithoutHanging) {
  TempDir dir;
  const std::string fifo = dir.file("task.yaml");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  auto result = std::async(std::launch::async, [&] { return errorOf([&] { readTextFile(fifo); }); });
  if (result.wait_for(std::chrono::seconds(10)) != std::future_status::ready) {
    // Blocked in open(): a writer releases it so the test fails instead of hanging.
    const int fd = ::open(fifo.c_str(), O_WRONLY | O_NONBLOCK);
    if (fd >= 0) ::close(fd);
    FAIL() << "readTextFile blocked on a FIFO";
  }
  const std::string message = result.get();
  EXPECT_NE(message.find(fifo), std::string::npos) << message;
  EXPECT_NE(message.find("FIFO"), std::string::npos) << message;

  auto streamed = std::async(std::launch::async, [&] { return errorOf([&] { ddace::InputFile in(fifo); }); });
  if (streamed.wait_for(std::chrono::seconds(10)) != std::future_status::ready) {
    const int fd = ::open(fifo.c_str(), O_WRONLY | O_NONBLOCK);
    if (fd >= 0) ::close(fd);
    FAIL() << "InputFile blocked on a FIFO";
  }
  EXPECT_NE(streamed.get().find("FIFO"), std::string::npos);
}

TEST(ReadTextFile, DevicesAreRefusedBeforeReading) {
  // /dev/zero would otherwise be read until memory runs out.
  const std::string message = errorOf([] { readTextFile("/dev/zero"); });
  EXPECT_NE(message.find("/dev/zero"), std::string::npos) << message;
  EXPECT_NE(message.find("character device"), std::string::npos) << message;
  EXPECT_NE(errorOf([] { ddace::InputFile in("/dev/zero"); }).find("character device"), std::string::npos);
}

TEST(ReadTextFile, DirectoryAndSymlinkLoopAreRefusedByName) {
  TempDir dir;
  fs::create_directory(dir.file("sub"));
  std::string message = errorOf([&] { readTextFile(dir.file("sub")); });
  EXPECT_NE(message.find(dir.file("sub")), std::string::npos) << message;
  EXPECT_NE(message.find("directory"), std::string::npos) << message;

  fs::create_symlink(dir.file("b"), dir.file("a"));
  fs::create_symlink(dir.file("a"), dir.file("b"));
  message = errorOf([&] { readTextFile(dir.file("a")); });
  EXPECT_NE(message.find(dir.file("a")), std::string::npos) << message;
  EXPECT_NE(message.find("symbolic links"), std::string::npos) << message;
}

TEST(ReadTextFile, SizeIsBounded) {
  TempDir dir;
  writeTextFile(dir.file("ten"), "0123456789");
  EXPECT_EQ(readTextFile(dir.file("ten"), 10), "0123456789");
  const std::string message = errorOf([&] { readTextFile(dir.file("ten"), 9); });
  EXPECT_NE(message.find(dir.file("ten")), std::string::npos) << message;
  EXPECT_NE(message.find("limit of 9 bytes"), std::string::npos) << message;
  EXPECT_GE(ddace::kMaxInputFileBytes, std::uint64_t{16} << 20);
}

TEST(InputFile, StreamsLinesAndTellsWhenTheBoundCutsTheFile) {
  TempDir dir;
  writeTextFile(dir.file("rows.csv"), "a,b\n1,2\n3,4\n");
  {
    ddace::InputFile in(dir.file("rows.csv"));
    std::vector<std::string> lines;
    for (std::string line; std::getline(in.stream(), line);) lines.push_back(line);
    EXPECT_EQ(lines, (std::vector<std::string>{"a,b", "1,2", "3,4"}));
    EXPECT_FALSE(in.exceeded());
  }
  {
    ddace::InputFile in(dir.file("rows.csv"), 100);
    std::string all((std::istreambuf_iterator<char>(in.stream())), std::istreambuf_iterator<char>());
    EXPECT_EQ(all.size(), 12u);
    EXPECT_FALSE(in.exceeded());
  }
  // A file that grows past the bound after it was opened: the stream stops at the bound.
  const std::string path = dir.file("growing.csv");
  writeTextFile(path, "12345");
  ddace::InputFile in(path, 8);
  {
    std::FILE* f = std::fopen(path.c_str(), "a");
    ASSERT_NE(f, nullptr);
    std::fputs("6789abc", f);
    std::fclose(f);
  }
  std::string all((std::istreambuf_iterator<char>(in.stream())), std::istreambuf_iterator<char>());
  EXPECT_EQ(all, "12345678");
  EXPECT_TRUE(in.exceeded());
}

TEST(WriteTextFile, RoundTripLeavesNoTemporaryFile) {
  TempDir dir;
  const std::string path = dir.file("task.yaml");
  writeTextFile(path, "first\n");
  writeTextFile(path, "second, longer\n");
  EXPECT_EQ(readTextFile(path), "second, longer\n");
  writeTextFile(path, "");
  EXPECT_EQ(readTextFile(path), "");
  std::string big(3 << 20, 'x');  // several buffer fills
  for (std::size_t i = 0; i < big.size(); i += 4099) big[i] = static_cast<char>('a' + i % 26);
  writeTextFile(path, big);
  EXPECT_EQ(readTextFile(path), big);
  EXPECT_EQ(dir.entries(), (std::vector<std::string>{"task.yaml"}));
}

TEST(WriteTextFile, DevFullFailsNamingTheFile) {
  // The bytes cannot be written: an error, never "wrote /dev/full".
  std::string message = errorOf([] { writeTextFile("/dev/full", "{\"osr\": 1.0}\n"); });
  EXPECT_NE(message.find("/dev/full"), std::string::npos) << message;
  EXPECT_NE(message.find("No space left on device"), std::string::npos) << message;
  message = errorOf([] { writeTextFile("/dev/full", std::string(1 << 20, 'x')); });
  EXPECT_NE(message.find("No space left on device"), std::string::npos) << message;
}

TEST(WriteTextFile, WritesIntoAPipeInPlace) {
  // `--json /dev/stdout` and process substitution name a pipe: written in place, checked.
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  writeTextFile("/dev/fd/" + std::to_string(fds[1]), "through the pipe\n");
  ::close(fds[1]);
  char buf[64] = {};
  const ssize_t n = ::read(fds[0], buf, sizeof buf);
  ::close(fds[0]);
  EXPECT_EQ(std::string(buf, n > 0 ? static_cast<std::size_t>(n) : 0), "through the pipe\n");
}

TEST(WriteTextFile, DirectoryOrMissingDirectoryIsAnErrorNamingTheFile) {
  TempDir dir;
  fs::create_directory(dir.file("out"));
  std::string message = errorOf([&] { writeTextFile(dir.file("out"), "x"); });
  EXPECT_NE(message.find(dir.file("out")), std::string::npos) << message;
  EXPECT_NE(message.find("directory"), std::string::npos) << message;
  message = errorOf([&] { writeTextFile(dir.file("no/such/dir/f.csv"), "x"); });
  EXPECT_NE(message.find(dir.file("no/such/dir/f.csv")), std::string::npos) << message;
  EXPECT_NE(message.find("No such file or directory"), std::string::npos) << message;
}

TEST(WriteTextFile, FailedWriteLeavesTheOldFileIntact) {
  TempDir dir;
  const std::string path = dir.file("demo.csv");
  writeTextFile(path, "t,x\n0,1\n");
  // In a child whose file-size limit makes the write fail (EFBIG) half way.
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    std::signal(SIGXFSZ, SIG_IGN);
    struct rlimit limit {};
    limit.rlim_cur = limit.rlim_max = 100000;
    ::setrlimit(RLIMIT_FSIZE, &limit);
    const std::string message = errorOf([&] { writeTextFile(path, std::string(1 << 20, 'y')); });
    const bool named = message.find(path) != std::string::npos && message.find("too large") != std::string::npos;
    ::_exit(named ? 0 : 1);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0) << "the write did not fail with an error naming the file";
  EXPECT_EQ(readTextFile(path), "t,x\n0,1\n");
  EXPECT_EQ(dir.entries(), (std::vector<std::string>{"demo.csv"}));
}

TEST(OutputFile, WithoutCommitNothingChanges) {
  TempDir dir;
  const std::string path = dir.file("model.yaml");
  writeTextFile(path, "old\n");
  {
    ddace::OutputFile out(path);
    out.stream() << "half of the new cont";
    // Leaves the scope without commit(), as an exception would.
  }
  EXPECT_EQ(readTextFile(path), "old\n");
  {
    ddace::OutputFile out(dir.file("new.yaml"));
    out.write("never committed");
  }
  EXPECT_EQ(dir.entries(), (std::vector<std::string>{"model.yaml"}));
}

TEST(OutputFile, KeepsTheModeAndFollowsSymlinks) {
  TempDir dir;
  const std::string real = dir.file("real.yaml");
  writeTextFile(real, "v1\n");
  ASSERT_EQ(::chmod(real.c_str(), 0640), 0);
  fs::create_symlink(real, dir.file("link.yaml"));
  {
    ddace::OutputFile out(dir.file("link.yaml"));
    out.stream() << "v" << 2 << "\n";
    out.commit();
  }
  EXPECT_TRUE(fs::is_symlink(dir.file("link.yaml")));
  EXPECT_EQ(readTextFile(real), "v2\n");
  struct stat st {};
  ASSERT_EQ(::stat(real.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0640u);
  EXPECT_EQ(dir.entries(), (std::vector<std::string>{"link.yaml", "real.yaml"}));
}

TEST(OutputFile, ReadOnlyFileIsRefusedNotReplaced) {
  if (::geteuid() == 0) GTEST_SKIP() << "root may write any file";
  TempDir dir;
  const std::string path = dir.file("locked.yaml");
  writeTextFile(path, "keep\n");
  ASSERT_EQ(::chmod(path.c_str(), 0444), 0);
  const std::string message = errorOf([&] { writeTextFile(path, "replaced\n"); });
  EXPECT_NE(message.find(path), std::string::npos) << message;
  EXPECT_NE(message.find("Permission denied"), std::string::npos) << message;
  EXPECT_EQ(readTextFile(path), "keep\n");
}
