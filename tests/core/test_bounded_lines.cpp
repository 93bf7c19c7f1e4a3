// The bounded line reader (core/file.h forEachLine) that every line-oriented file goes through:
// lines as written (any byte, a last line without '\n' marked), and bombs refused in bounded
// time and memory: a file over its size limit from its size alone (a sparse file of 64 GiB), a
// line over its length limit as soon as it is (a long line without '\n', NUL bytes after three
// good lines), a FIFO or a directory without a hang.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "common/hostile.h"
#include "common/temp_dir.h"
#include "core/error.h"
#include "core/file.h"

using namespace refgrasp;
using refgrasp::testing::configErrorOf;
namespace fs = std::filesystem;

namespace {

fs::path dir() { return refgrasp::testing::tempDir("refgrasp_test_bounded_lines"); }

std::string write(const std::string& name, const std::string& bytes) {
  const fs::path p = dir() / name;
  std::ofstream(p, std::ios::binary | std::ios::trunc) << bytes;
  return p.string();
}

// `head` followed by NUL bytes up to `size` bytes: a sparse file, cheap whatever its size.
std::string sparse(const std::string& name, const std::string& head, off_t size) {
  const std::string p = write(name, head);
  EXPECT_EQ(::truncate(p.c_str(), size), 0);
  return p;
}

struct Seen {
  uint64_t number;
  std::string text;
  bool complete;
};

std::vector<Seen> lines(const std::string& path, uint64_t max_total, uint64_t max_line,
                        size_t stop_after = SIZE_MAX) {
  std::vector<Seen> out;
  forEachLine(path, max_total, max_line, [&](const TextLine& l) {
    out.push_back({l.number, std::string(l.text), l.complete});
    return out.size() < stop_after;
  });
  return out;
}

double secondsOf(const std::function<void()>& f) {
  const auto t0 = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

TEST(BoundedLines, LinesAreDeliveredAsWrittenWithTheirNumbers) {
  const std::string nul("a\0b", 3);
  const std::vector<Seen> got = lines(write("plain.txt", "one\r\n\n" + nul + "\nlast"), 100, 10);
  ASSERT_EQ(got.size(), 4u);
  EXPECT_EQ(got[0].text, "one\r");  // '\r' kept: the caller trims what it does not want
  EXPECT_EQ(got[1].text, "");
  EXPECT_EQ(got[2].text, nul);
  EXPECT_EQ(got[3].text, "last");
  for (size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i].number, i + 1);
    EXPECT_EQ(got[i].complete, i < 3) << i;  // the last has no '\n': a write cut short
  }
  EXPECT_TRUE(lines(write("empty.txt", ""), 100, 10).empty());
  EXPECT_EQ(lines(write("stop.txt", "1\n2\n3\n"), 100, 10, 2).size(), 2u);  // fn returned false
  // Lines across the reader's 64 KiB chunks, up to exactly the limit.
  const std::string a(100000, 'a'), b(150000, 'b');
  const std::vector<Seen> big = lines(write("big.txt", a + "\n" + b + "\n"), 1 << 20, 150000);
  ASSERT_EQ(big.size(), 2u);
  EXPECT_EQ(big[0].text, a);
  EXPECT_EQ(big[1].text, b);
  EXPECT_EQ(configErrorOf([&] { lines(write("big.txt", a + "\n" + b + "\n"), 1 << 20, 149999); }),
            (dir() / "big.txt").string() + ": line 2: longer than the limit of 149999 bytes");
  // A last line without '\n' is held to the limit too.
  EXPECT_EQ(configErrorOf([&] { lines(write("tail.txt", "ok\n" + a), 1 << 20, 1000); }),
            (dir() / "tail.txt").string() + ": line 2: longer than the limit of 1000 bytes");
}

TEST(BoundedLines, AFileOverItsSizeLimitIsRefusedFromItsSizeBeforeAnyLine) {
  const off_t huge = off_t{64} << 30;  // 64 GiB, sparse
  const std::string p = sparse("huge.jsonl", "{\"frame\": 0}\n", huge);
  int calls = 0;
  std::string e;
  const double s = secondsOf([&] {
    e = configErrorOf([&] {
      forEachLine(p, uint64_t{16} << 30, 1 << 20, [&](const TextLine&) { return ++calls > 0; });
    });
  });
  EXPECT_EQ(e, p + ": is 68719476736 bytes, more than the limit of 17179869184");
  EXPECT_EQ(calls, 0);
  EXPECT_LT(s, 0.5);
}

TEST(BoundedLines, ALongLineOrNulBytesStopTheReadAtTheLimitInBoundedTime) {
  // A recording bomb: three lines, then NUL bytes (here 3 GiB of them, sparse) and no '\n'.
  const std::string p = sparse("nul.jsonl", "{}\n{}\n{}\n", off_t{3} << 30);
  int calls = 0;
  std::string e;
  double s = secondsOf([&] {
    e = configErrorOf([&] {
      forEachLine(p, uint64_t{16} << 30, 1 << 20, [&](const TextLine&) { return ++calls > 0; });
    });
  });
  EXPECT_EQ(e, p + ": line 4: longer than the limit of 1048576 bytes");
  EXPECT_EQ(calls, 3);
  EXPECT_LT(s, 2.0);
  // A long line of text without '\n'.
  const std::string q = write("long.txt", std::string(8 << 20, '7'));
  s = secondsOf([&] { e = configErrorOf([&] { lines(q, 1 << 30, 64 << 10); }); });
  EXPECT_EQ(e, q + ": line 1: longer than the limit of 65536 bytes");
  EXPECT_LT(s, 2.0);
}

TEST(BoundedLines, FifoDirectoryAndMissingFileAreOneLineErrorsNotHangs) {
  const std::string fifo = (dir() / "pipe.txt").string();
  fs::remove(fifo);
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_EQ(configErrorOf([&] { lines(fifo, 100, 10); }), fifo + ": is a FIFO, not a regular file");
  EXPECT_EQ(configErrorOf([&] { lines(dir().string(), 100, 10); }),
            dir().string() + ": is a directory, expected a file");
  EXPECT_EQ(configErrorOf([&] { lines("/dev/zero", 100, 10); }),
            "/dev/zero: is a character device, not a regular file");
  EXPECT_EQ(configErrorOf([&] { lines((dir() / "none.txt").string(), 100, 10); }),
            (dir() / "none.txt").string() + ": file not found");
  // An exception from the callback reaches the caller as it is.
  EXPECT_EQ(configErrorOf([&] {
              forEachLine(write("cb.txt", "x\n"), 100, 10, [](const TextLine& l) -> bool {
                throw ConfigError("cb.txt", "line " + std::to_string(l.number), "refused");
              });
            }),
            "cb.txt: line 1: refused");
}
