// The paper's Fig. 7 / Fig. 8 pipeline (eval/paper_figures.h) in its --quick form: a smoke test
// of the pipeline (scenes, detectors, scoring, tables, plots, the page), not of the figures.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <opencv2/core.hpp>
#include <regex>
#include <sstream>

#include "common/temp_dir.h"
#include "core/image_io.h"
#include "eval/paper_figures.h"

using namespace refgrasp;
using namespace refgrasp::eval;

namespace fs = std::filesystem;

namespace {

std::string configDir() { return std::string(REFGRASP_SOURCE_DIR) + "/config"; }

std::vector<std::string> tableRows(const std::string& text, const std::string& first_cell) {
  std::vector<std::string> rows;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);)
    if (line.rfind("| " + first_cell + " |", 0) == 0) rows.push_back(line);
  return rows;
}

int cells(const std::string& row) { return static_cast<int>(std::count(row.begin(), row.end(), '|')) - 1; }

}  // namespace

TEST(PaperFigures, TheSixObjectsAndTheirGeometry) {
  const std::vector<PaperObject> objects = paperObjects({0, 30, 60}, {30, 45, 60});
  ASSERT_EQ(objects.size(), 6u);
  int planar = 0, boxes = 0, round = 0;
  for (const PaperObject& o : objects) {
    planar += o.shape == PaperShape::kPlanar;
    boxes += o.shape == PaperShape::kBox;
    round += o.round();
    EXPECT_TRUE(o.model.has3d()) << o.name;
    EXPECT_EQ(o.model.isCylinder(), o.round()) << o.name;
    EXPECT_EQ(o.cylinder.has_value(), o.round()) << o.name;
    EXPECT_EQ(o.faces.empty(), o.round()) << o.name;
    EXPECT_EQ(o.turns_deg.size(), 3u);
  }
  EXPECT_EQ(planar, 3);
  EXPECT_EQ(boxes, 1);
  EXPECT_EQ(round, 2);
  // The can and the bottle: the sizes of the brief, the label all the way round.
  EXPECT_NEAR(objects[4].model.cylinder->radius_m, 0.033, 1e-12);
  EXPECT_NEAR(objects[4].model.cylinder->height_m, 0.115, 1e-12);
  EXPECT_NEAR(objects[4].model.cylinder->width_m, 2 * M_PI * 0.033, 1e-9);
  EXPECT_NEAR(objects[5].model.cylinder->radius_m, 0.04, 1e-12);
  EXPECT_GT(objects[5].model.cylinder->height_m, 0.115);
  // The box's front (its definition) is in view together with a neighbouring face at every turn.
  for (double t : objects[3].turns_deg) {
    EXPECT_GE(t, 20.0);
    EXPECT_LE(t, 70.0);
  }
}

TEST(PaperFigures, AViewIsPointedAtTheObjectAtTheRequestedDistance) {
  Fig7Options opt;
  opt.config_dir = configDir();
  const std::vector<PaperObject> objects = paperObjects({0}, {45});
  for (double d : {0.5, 3.0}) {
    Pose cMo;
    const cv::Mat img = renderFig7View(opt, objects[0], d, 0, &cMo);
    ASSERT_EQ(img.type(), CV_8UC1);
    EXPECT_EQ(img.cols, 640);
    // The head points at the card's centre (the object origin): near the principal point.
    EXPECT_NEAR(cMo.t.x() / cMo.t.z(), 0, 0.01) << d;
    EXPECT_NEAR(cMo.t.y() / cMo.t.z(), 0, 0.01) << d;
    // Horizontal distance d from the head axis, the eye ~1.25 m above the floor (it sits 5 cm in
    // front of the tilt axis and 3 cm above, so looking down brings it forward and down by a few
    // cm), the card's centre 0.72 + 0.034 m.
    const double below = 1.25 - 0.72 - 0.0344;
    EXPECT_NEAR(cMo.t.norm(), std::hypot(d - 0.05, below), 0.05) << d;
    // Facing the robot (turn 0): the card's z axis is horizontal, away from the robot, so it makes
    // the angle of the camera's look down with the viewing ray.
    EXPECT_NEAR(cMo.R.col(2).dot(cMo.t.normalized()), std::cos(std::atan2(below, d - 0.05)), 0.05) << d;
  }
}

TEST(PaperFigures, BadOptionsThrowNamingTheField) {
  Fig7Options a;
  a.frames = 0;
  EXPECT_THROW(
      try { a.check(); } catch (const std::invalid_argument& e) {
        EXPECT_STREQ(e.what(), "Fig7Options.frames: must be >= 1");
        throw;
      },
      std::invalid_argument);
  Fig7Options b;
  b.distances_m = {0.5, 9};
  EXPECT_THROW(b.check(), std::invalid_argument);
  Fig8Options c;
  c.frame_rate_hz = 100;
  EXPECT_THROW(c.check(), std::invalid_argument);
  Fig8Options d;
  d.duration_s = NAN;
  EXPECT_THROW(d.check(), std::invalid_argument);
}

// The --quick run end to end: every file written, the tables' rows and columns, values in range.
TEST(PaperFigures, TheQuickRunWritesThePageTablesAndPlots) {
  cv::setNumThreads(1);
  Fig7Options o7;
  Fig8Options o8;
  o7.config_dir = o8.config_dir = configDir();
  makeQuick(&o7, &o8);
  o7.threads = 2;
  int progress = 0;
  const Fig7Result r7 = runFig7(o7, [&](int done, int total) {
    EXPECT_EQ(total, 12);
    progress = done;
  });
  EXPECT_EQ(progress, 12);
  ASSERT_EQ(r7.objects.size(), 6u);
  ASSERT_EQ(r7.cells.size(), 12u);  // 6 objects x 2 distances x 1 turn
  ASSERT_EQ(r7.rows.size(), (4 * 2 + 2 * 3) * 2u);
  for (const Fig7Row& row : r7.rows) {
    EXPECT_EQ(row.frames, 2);
    EXPECT_GE(row.success, row.pose_ok);
    EXPECT_LE(row.success + row.wrong, row.frames);
    if (std::isfinite(row.std_m.z())) {
      EXPECT_GE(row.std_m.minCoeff(), 0.0);
      EXPECT_LT(row.std_m.maxCoeff(), 0.05 * row.distance_m);  // successes lie within 5 % of the truth
    }
  }
  // The nearest flat card, turned 30 deg, 0.5 m away: refgrasp finds it in both noisy frames.
  const auto near = r7.rowsOf(0, Fig7Method::kRefined);
  ASSERT_EQ(near.size(), 2u);
  EXPECT_EQ(near[0]->success, 2);

  const Fig8Result r8 = runFig8(o8);
  ASSERT_EQ(r8.frames.size(), 48u);  // 3 s at 16 frames per second
  EXPECT_EQ(r8.collisions, 0);
  for (size_t i = 0; i < r8.frames.size(); ++i) {
    EXPECT_NEAR(r8.frames[i].t_s, i / 16.0, 0.03);
    ASSERT_EQ(r8.frames[i].raw.size(), 6u);
    for (size_t k = 0; k < 6; ++k) EXPECT_LE(r8.frames[i].confirmed[k], r8.frames[i].raw[k] + 1);
  }
  // The robot moved (a turn on the spot) and its head swept.
  EXPECT_GT(std::abs(r8.frames.back().pan_rad - r8.frames.front().pan_rad), 0.3);
  // None of the six is in the room: nothing may be confirmed.
  for (int c : r8.confirmedTotals()) EXPECT_EQ(c, 0);

  const fs::path dir = refgrasp::testing::tempDir("refgrasp_paper_figures");
  const std::vector<std::string> written = writePaperReport(dir.string(), r7, r8, "paper_figures --quick");
  ASSERT_EQ(written.size(), 5u);
  for (const char* png : {"fig7_success.png", "fig7_pose_std.png", "fig7_views.png", "fig8_false_positives.png"}) {
    const ImageRead img = readImage((dir / "img" / png).string(), ImageMode::kColor);
    ASSERT_TRUE(img.ok()) << png << ": " << img.error;
    EXPECT_GE(img.image.cols, 900) << png;
    EXPECT_GE(img.image.rows, 300) << png;
  }
  std::ifstream f(dir / "evaluation.md");
  std::stringstream ss;
  ss << f.rdbuf();
  const std::string md = ss.str();
  for (const char* s : {"img/fig7_success.png", "img/fig7_pose_std.png", "img/fig8_false_positives.png",
                        "0.001(m) for planar objects", "over 73 seconds", "paper_figures --quick"})
    EXPECT_NE(md.find(s), std::string::npos) << s;
  // Nothing dated in the generated page (tests/docs): no date, no issue number.
  EXPECT_FALSE(std::regex_search(md, std::regex("20[0-9]{2}-[0-9]{2}-[0-9]{2}")));
  // Fig. 7: per object, 2 rows (planar) or 3 (round) in each of the four tables (the page adds
  // the object's line in the set-up table and in the Fig. 8 table); the success and std tables'
  // rows have the object, the method and one cell per distance, the by-turn table's three cells,
  // the summary's six.
  const std::string tables = fig7Tables(r7);
  EXPECT_NE(md.find(tables), std::string::npos);
  for (const PaperObject& o : r7.objects) {
    const size_t methods = o.round() ? 3 : 2;
    const std::vector<std::string> rows = tableRows(tables, o.name);
    ASSERT_EQ(rows.size(), 4 * methods) << o.name;
    for (size_t k = 0; k < rows.size(); ++k)
      EXPECT_EQ(cells(rows[k]), k < 2 * methods ? 2 + 2 : k < 3 * methods ? 3 : 6) << rows[k];
    EXPECT_EQ(tableRows(md, o.name).size(), rows.size() + 2);
    // Fig. 8: one row per object: six columns, 48 frames.
    const std::vector<std::string> fp = tableRows(fig8Table(r8), o.name);
    ASSERT_EQ(fp.size(), 1u);
    EXPECT_EQ(cells(fp[0]), 6);
    EXPECT_NE(fp[0].find("| 48 |"), std::string::npos);
  }
  std::regex pct(R"(\| (\d+) \((\d+)\))");
  int checked = 0;
  for (std::sregex_iterator it(md.begin(), md.end(), pct), end; it != end; ++it, ++checked) {
    const int s = std::stoi((*it)[1]), p = std::stoi((*it)[2]);
    EXPECT_LE(s, 100);
    EXPECT_LE(p, s);
  }
  EXPECT_EQ(checked, 14 * 2);  // 14 object-method rows x 2 distances
  std::regex by_turn(R"(deg: (\d+) \((\d+)\))");
  checked = 0;
  for (std::sregex_iterator it(md.begin(), md.end(), by_turn), end; it != end; ++it, ++checked) {
    const int s = std::stoi((*it)[1]), p = std::stoi((*it)[2]);
    EXPECT_LE(s, 100);
    EXPECT_LE(p, s);
  }
  EXPECT_EQ(checked, 14);  // 14 object-method rows x 1 turn
  fs::remove_all(dir);
}
