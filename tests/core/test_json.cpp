// The pose JSON codec: both forms round-trip, field order as documented, bad input names the field.
#include <gtest/gtest.h>

#include "core/error.h"
#include "core/json.h"

using namespace refgrasp;

TEST(PoseJson, BothFormsRoundTripInTheDocumentedOrder) {
  const Pose p = Pose::fromRotationVector({0.3, -0.2, 1.1}, {0.05, -0.02, 0.8});
  const Json m = poseJson(p);
  EXPECT_EQ(m.dump().substr(0, 6), "{\"R\":[");
  ASSERT_EQ(m["R"].size(), 9u);
  EXPECT_DOUBLE_EQ(m["R"][1].get<double>(), p.R(0, 1));  // row-major
  EXPECT_DOUBLE_EQ(m["R"][3].get<double>(), p.R(1, 0));
  EXPECT_EQ(m["t"], Json::array({0.05, -0.02, 0.8}));
  const Pose back = poseFromJson(Json::parse(m.dump()));
  EXPECT_EQ((back.R - p.R).norm(), 0.0);  // 17 significant digits: exact
  EXPECT_EQ((back.t - p.t).norm(), 0.0);

  const Json v = poseJson(p, PoseJsonForm::kRotationVector);
  EXPECT_EQ(v.dump().substr(0, 6), "{\"t\":[");
  EXPECT_EQ(std::next(v.begin()).key(), "rotation_vector");
  const Pose back_v = poseFromJson(v);
  EXPECT_LT(rotationError(back_v, p), 1e-12);
  EXPECT_EQ((back_v.t - p.t).norm(), 0.0);

  // putPose keeps existing keys in place and appends new ones.
  Json line = {{"image", "a.png"}, {"R", 0}, {"t", 0}, {"inliers", 3}};
  putPose(&line, p);
  EXPECT_EQ(line.begin().key(), "image");
  EXPECT_EQ(std::next(line.begin(), 3).key(), "inliers");
  EXPECT_EQ(line["R"].size(), 9u);
}

TEST(PoseJson, BadInputNamesTheField) {
  struct Case {
    const char* json;
    const char* expect;
  };
  const Case cases[] = {
      {R"({"R":[1,0,0,0,1,0,0,0,1]})", "src: t: missing"},
      {R"({"R":[1,0,0,0,1,0,0,0],"t":[0,0,1]})", "src: R: expected 9 numbers"},
      {R"({"R":[2,0,0,0,1,0,0,0,1],"t":[0,0,1]})", "src: R: not a rotation matrix"},
      {R"({"R":[-1,0,0,0,1,0,0,0,1],"t":[0,0,1]})", "src: R: not a rotation matrix"},
      {R"({"t":[0,"x",1],"rotation_vector":[0,0,0]})", "src: t: expected 3 numbers"},
      {R"({"t":[0,0,1]})", "src: R: missing (or rotation_vector)"},
      {R"({"t":[0,0,1],"rotation_vector":[0,0]})", "src: rotation_vector: expected 3 numbers"},
      {R"([1,2])", "src: expected an object"},
  };
  for (const Case& c : cases) {
    try {
      poseFromJson(Json::parse(c.json), "src");
      ADD_FAILURE() << c.json;
    } catch (const ConfigError& e) {
      EXPECT_EQ(std::string(e.what()).rfind(c.expect, 0), 0u) << c.json << ": " << e.what();
    }
  }
}
