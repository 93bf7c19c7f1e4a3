// The documentation as a tree of pages: every relative link and image in the project's markdown
// resolves (the file exists; for `page.md#anchor`, a heading of that page has the GitHub slug
// `anchor`), and README.md stays a front page (short, nothing dated).
#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "common/temp_dir.h"

namespace fs = std::filesystem;

namespace {

const fs::path kSource = REFGRASP_SOURCE_DIR;

std::vector<std::string> readLines(const fs::path& file) {
  std::ifstream in(file);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

// A fence opens with three or more backticks or tildes (after up to three spaces of indent, or
// inside a list item) and closes with the same character.
bool fenceLine(const std::string& line, char* fence) {
  const size_t i = line.find_first_not_of(' ');
  if (i == std::string::npos || line.size() < i + 3) return false;
  const char c = line[i];
  if ((c != '`' && c != '~') || line[i + 1] != c || line[i + 2] != c) return false;
  if (*fence == 0) {
    *fence = c;
  } else if (*fence == c) {
    *fence = 0;
  }
  return true;
}

// The text without its inline code spans (`...`, ``...``), whose line breaks are kept: a bracket
// inside code is no link.
std::string withoutCodeSpans(const std::string& text) {
  std::string out;
  for (size_t i = 0; i < text.size();) {
    if (text[i] != '`') {
      out += text[i++];
      continue;
    }
    size_t run = 0;
    while (i + run < text.size() && text[i + run] == '`') ++run;
    const std::string ticks(run, '`');
    const size_t close = text.find(ticks, i + run);
    if (close == std::string::npos) {  // an unmatched backtick is literal text
      out += ticks;
      i += run;
    } else {
      out.append(static_cast<size_t>(std::count(text.begin() + i, text.begin() + close, '\n')), '\n');
      i = close + run;
    }
  }
  return out;
}

// GitHub's heading anchor: lower case, spaces to '-', punctuation other than '-' and '_'
// removed (bytes of non-ASCII letters kept); a repeated slug gets "-1", "-2", ...
std::string slug(const std::string& heading) {
  std::string s;
  for (const unsigned char c : heading) {
    if (std::isalnum(c) || c == '-' || c == '_' || c >= 0x80) {
      s += static_cast<char>(std::tolower(c));
    } else if (c == ' ') {
      s += '-';
    }
  }
  return s;
}

std::set<std::string> anchors(const fs::path& page) {
  std::set<std::string> out;
  std::map<std::string, int> seen;
  char fence = 0;
  static const std::regex kHeading(R"(^ {0,3}#{1,6}\s+(.*?)\s*#*\s*$)");
  for (const std::string& line : readLines(page)) {
    if (fenceLine(line, &fence) || fence) continue;
    std::smatch m;
    if (!std::regex_match(line, m, kHeading)) continue;
    const std::string base = slug(m[1].str());
    const int n = seen[base]++;
    out.insert(n == 0 ? base : base + "-" + std::to_string(n));
  }
  return out;
}

// Every `[text](target)` and `![alt](target)` outside code whose target is not a URL, checked
// against the tree: "file:line: target" for each one that does not resolve. A paragraph is read
// as a whole, so a link text may run over several lines; the line is the target's.
std::vector<std::string> brokenLinks(const fs::path& root, const std::vector<fs::path>& pages) {
  static const std::regex kLink(R"(!?\[[^\]]*\]\(\s*<?([^)\s>]*)>?(?:\s+"[^"]*")?\s*\))");
  std::vector<std::string> broken;
  std::map<fs::path, std::set<std::string>> anchor_cache;
  for (const fs::path& page : pages) {
    const std::vector<std::string> lines = readLines(page);
    char fence = 0;
    std::string paragraph;
    size_t first_line = 0;  // 0-based line of the paragraph's start
    const auto check = [&]() {
      const std::string text = withoutCodeSpans(paragraph);
      for (auto it = std::sregex_iterator(text.begin(), text.end(), kLink); it != std::sregex_iterator();
           ++it) {
        const std::string target = (*it)[1].str();
        if (target.rfind("http://", 0) == 0 || target.rfind("https://", 0) == 0 ||
            target.rfind("mailto:", 0) == 0)
          continue;
        const size_t hash = target.find('#');
        const std::string file_part = target.substr(0, hash);
        const std::string anchor = hash == std::string::npos ? "" : target.substr(hash + 1);
        const fs::path resolved =
            file_part.empty() ? page : (page.parent_path() / file_part).lexically_normal();
        bool ok = !target.empty() && fs::exists(resolved);
        if (ok && !anchor.empty() && resolved.extension() == ".md") {
          auto found = anchor_cache.find(resolved);
          if (found == anchor_cache.end()) found = anchor_cache.emplace(resolved, anchors(resolved)).first;
          ok = found->second.count(anchor) > 0;
        }
        if (!ok) {
          const size_t at = static_cast<size_t>(it->position(1));
          const size_t line = first_line + 1 + static_cast<size_t>(std::count(text.begin(), text.begin() + at, '\n'));
          broken.push_back(page.lexically_relative(root).string() + ":" + std::to_string(line) + ": " + target);
        }
      }
      paragraph.clear();
    };
    for (size_t n = 0; n < lines.size(); ++n) {
      const bool code = fenceLine(lines[n], &fence) || fence;
      if (code || lines[n].find_first_not_of(" \t") == std::string::npos) {
        check();
        continue;
      }
      if (paragraph.empty()) {
        first_line = n;
      } else {
        paragraph += '\n';
      }
      paragraph += lines[n];
    }
    check();
  }
  return broken;
}

// The pages checked: the front page, DEVELOPERS.md, the two folder READMEs and docs/**/*.md.
std::vector<fs::path> projectPages() {
  std::vector<fs::path> pages = {kSource / "README.md", kSource / "DEVELOPERS.md",
                                 kSource / "config/scenarios/README.md", kSource / "media/README.md"};
  std::vector<fs::path> docs;
  for (const auto& e : fs::recursive_directory_iterator(kSource / "docs"))
    if (e.is_regular_file() && e.path().extension() == ".md") docs.push_back(e.path());
  std::sort(docs.begin(), docs.end());
  pages.insert(pages.end(), docs.begin(), docs.end());
  return pages;
}

std::string joined(const std::vector<std::string>& items) {
  std::string s;
  for (const std::string& i : items) s += "\n  " + i;
  return s;
}

void write(const fs::path& file, const std::string& text) {
  fs::create_directories(file.parent_path());
  std::ofstream(file) << text;
}

}  // namespace

TEST(Docs, EveryRelativeLinkResolves) {
  const std::vector<fs::path> pages = projectPages();
  ASSERT_GE(pages.size(), 5u) << "docs/ has no pages";
  for (const fs::path& p : pages) ASSERT_TRUE(fs::is_regular_file(p)) << p;
  const std::vector<std::string> broken = brokenLinks(kSource, pages);
  EXPECT_TRUE(broken.empty()) << broken.size() << " broken link(s):" << joined(broken);
}

namespace {

// Text that belongs in docs/results.md (dated measurements) or in commit messages (history):
// a date, an issue number, the data splits a figure was developed or reported on. The patterns
// are written so that this file does not match them itself.
const std::vector<std::pair<std::string, std::regex>>& datedText() {
  static const std::vector<std::pair<std::string, std::regex>> dated = {
      {"a date", std::regex("20[0-9]{2}-[0-9]{2}-[0-9]{2}")},
      {"an issue number", std::regex("issue [0-9]+", std::regex::icase)},
      {"a tuning split", std::regex("develop[m]ent (seed|split)", std::regex::icase)},
      {"the reported split", std::regex("repor[t] split", std::regex::icase)},
  };
  return dated;
}

std::vector<std::string> datedLines(const fs::path& file, const std::string& name) {
  std::vector<std::string> found;
  const std::vector<std::string> lines = readLines(file);
  for (size_t n = 0; n < lines.size(); ++n)
    for (const auto& [what, re] : datedText())
      if (std::regex_search(lines[n], re)) found.push_back(name + ":" + std::to_string(n + 1) + ": " + what);
  return found;
}

}  // namespace

TEST(Docs, TheReadmeIsAFrontPage) {
  const std::vector<std::string> lines = readLines(kSource / "README.md");
  EXPECT_LE(lines.size(), 250u) << "README.md is a front page; the rest belongs in docs/";
  const std::vector<std::string> found = datedLines(kSource / "README.md", "README.md");
  EXPECT_TRUE(found.empty()) << "dated text belongs in docs/results.md:" << joined(found);
}

// Comments in src/, app/ and tests/ state meaning; dates, issue numbers and the data a figure was
// tuned on belong in docs/results.md and the commit messages.
TEST(Docs, SourcesCarryNoDatesIssueNumbersOrTuningSplits) {
  std::vector<std::string> found;
  int files = 0;
  for (const char* room : {"src", "app", "tests"})
    for (const auto& entry : fs::recursive_directory_iterator(kSource / room)) {
      if (!entry.is_regular_file()) continue;
      const std::string ext = entry.path().extension().string();
      if (ext != ".h" && ext != ".cpp" && ext != ".c" && ext != ".inl" && ext != ".sh" && ext != ".txt") continue;
      ++files;
      const std::vector<std::string> f = datedLines(entry.path(), fs::relative(entry.path(), kSource).string());
      found.insert(found.end(), f.begin(), f.end());
    }
  EXPECT_GT(files, 100) << "the source tree was not found";
  EXPECT_TRUE(found.empty()) << found.size() << " line(s):" << joined(found);
}

// The checker itself, on a small tree: it must see a missing file, a missing anchor and a link
// text with code in it, and must not see links in code or URLs.
TEST(Docs, TheLinkCheckerFindsWhatIsBrokenAndNothingElse) {
  const fs::path root = refgrasp::testing::tempDir("refgrasp_docs_links");
  fs::remove_all(root);
  write(root / "docs/a.md",
        "# Page A\n"
        "## Heading, with (punctuation) and `code`\n"
        "## Repeated\n"
        "## Repeated\n"
        "```\n"
        "[inside a fence](missing_in_fence.md)\n"
        "## not a heading\n"
        "```\n"
        "Good: [b](b.md), [self](#page-a), [h](#heading-with-punctuation-and-code), "
        "[dup](#repeated-1), ![img](../img.png), [`code text`](b.md#page-b), <https://x.org>, "
        "[web](https://example.org/missing), `[in code](missing_in_code.md)`.\n"
        "Bad: [gone](gone.md) and [no anchor](b.md#nowhere)\n"
        "[fenced heading](#not-a-heading) [dup too far](#repeated-2)\n"
        "\n"
        "A [link over\ntwo lines](b.md#page-b) and [another\none](b.md#page-c).\n");
  write(root / "docs/b.md", "# Page B\n");
  write(root / "img.png", "");
  const std::vector<std::string> broken = brokenLinks(root, {root / "docs/a.md"});
  const std::vector<std::string> expected = {"docs/a.md:10: gone.md", "docs/a.md:10: b.md#nowhere",
                                             "docs/a.md:11: #not-a-heading", "docs/a.md:11: #repeated-2",
                                             "docs/a.md:15: b.md#page-c"};
  EXPECT_EQ(broken, expected) << joined(broken);
  fs::remove_all(root);
}
