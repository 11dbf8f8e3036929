// rostest of the `set` tool (src/nodes/set.cpp): it changes the detector's parameters through
// /detector/set_parameters, prints what the detector now holds, and refuses a bad name or value without calling.
// What changed is read back independently: from the parameter server (dynamic_reconfigure writes each value there)
// and from the detector's ~status (the distance it was asked for).
#include <gtest/gtest.h>
#include <ros/ros.h>

#include <atomic>
#include <string>

#include "clod_haptics/DetectorStatus.h"
#include "run_command.h"

namespace {

using clod_haptics_test::Outcome;
using clod_haptics_test::run;
using clod_haptics_test::waitUntil;

const std::string kSet = CLOD_SET_PATH;

double paramDouble(const std::string& name) {
  double v = -1.0;
  ros::param::get(name, v);
  return v;
}

std::string paramString(const std::string& name) {
  std::string v;
  ros::param::get(name, v);
  return v;
}

class SetTool : public ::testing::Test {
 protected:
  void SetUp() override {
    ros::NodeHandle nh;
    statusSub_ = nh.subscribe("/detector/status", 10, &SetTool::onStatus, this);
    spinner_.start();
    ASSERT_TRUE(waitUntil([] { return ros::service::exists("/detector/set_parameters", false); }, 30.0));
  }
  void TearDown() override {  // no callback may run once requested_ is gone
    spinner_.stop();
    statusSub_.shutdown();
  }
  void onStatus(const clod_haptics::DetectorStatusConstPtr& s) { requested_ = s->requested_distance; }

  ros::Subscriber statusSub_;
  ros::AsyncSpinner spinner_{1};
  std::atomic<double> requested_{-1.0};
};

TEST_F(SetTool, SetsValuesByNameAndAlias) {
  const Outcome o = run(kSet + " distance 0.005 mode paper stiffness 250 show_spheres true");
  ASSERT_EQ(o.exitCode, 0) << o.output;
  EXPECT_NE(o.output.find("clustering_distance: 0.005"), std::string::npos) << o.output;
  EXPECT_NE(o.output.find("detection_mode: paper"), std::string::npos) << o.output;
  EXPECT_NE(o.output.find("answered in"), std::string::npos) << o.output;
  EXPECT_DOUBLE_EQ(paramDouble("/detector/clustering_distance"), 0.005);
  EXPECT_EQ(paramString("/detector/detection_mode"), "paper");
  EXPECT_DOUBLE_EQ(paramDouble("/detector/stiffness"), 250.0);
  bool spheres = false;
  EXPECT_TRUE(ros::param::get("/detector/show_spheres", spheres) && spheres);
  EXPECT_TRUE(waitUntil([&] { return requested_.load() == 0.005; }, 10.0)) << "status says " << requested_.load();
}

TEST_F(SetTool, WithoutArgumentsPrintsEveryValue) {
  const Outcome o = run(kSet + " --detector /detector");
  ASSERT_EQ(o.exitCode, 0) << o.output;
  for (const char* name : {"clustering_distance:", "pointer_radius:", "force_model:", "show_pointer:"})
    EXPECT_NE(o.output.find(name), std::string::npos) << name << " missing: " << o.output;
}

TEST_F(SetTool, RefusesBadNamesAndValuesAndChangesNothing) {
  ASSERT_EQ(run(kSet + " radius 0.003").exitCode, 0);
  const struct {
    const char* args;
    const char* mention;
  } bad[] = {{"nosuch 1", "known:"},          {"radius abc", "not a finite number"}, {"radius 5", "outside"},
             {"radius", "pairs"},             {"show_mesh maybe", "true or false"},   {"radius 0.004 radius", "pairs"}};
  for (const auto& b : bad) {
    const Outcome o = run(kSet + " " + b.args);
    EXPECT_EQ(o.exitCode, 2) << b.args << ": " << o.output;
    EXPECT_NE(o.output.find(b.mention), std::string::npos) << b.args << ": " << o.output;
  }
  EXPECT_DOUBLE_EQ(paramDouble("/detector/pointer_radius"), 0.003);
}

TEST_F(SetTool, NoDetectorIsAnErrorNotAHang) {
  const Outcome o = run(kSet + " --detector /nobody distance 0.004");
  EXPECT_EQ(o.exitCode, 1) << o.output;
  EXPECT_NE(o.output.find("/nobody/set_parameters"), std::string::npos) << o.output;
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_set_parameter");
  return RUN_ALL_TESTS();
}
