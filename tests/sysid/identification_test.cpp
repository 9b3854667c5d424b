// SPDX-License-Identifier: BSD-3-Clause
// sysid::IdentifyVehicle without its data: every stage fails with the reason its data could
// not be loaded (the PD stage because the attitude model failed), nothing is written into
// the report's tables, and the vehicle keeps only what the campaign gives (mass, arm length).
// The stages on real data: tests/sysid's round trip and the held-out / model-choice tests.
#include "fnmpc/sysid/identification.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

namespace fnmpc::sysid {
namespace {

TEST(IdentifyVehicleTest, EachStageWithoutItsDataFailsWithTheLoadError) {
  IdentificationData data;
  data.mass = 1.2;
  data.arm_length = 0.2;
  data.wire_separation = 0.3;
  data.wire_length = 1.0;
  data.bench.error = "bench.csv: cannot read";
  for (Loaded<PendulumSwing>& p : data.pendulum) p.error = "pendulum_x.csv: cannot read";
  data.attitude_steps.error = "attitude_steps.csv: missing column 'yaw'";
  const Identification id = IdentifyVehicle(data, IdentificationSettings{});
  ASSERT_EQ(id.stages.size(), 4U);
  EXPECT_EQ(id.stages[0].name, "propulsion");
  for (const StageReport& s : id.stages) EXPECT_FALSE(s.ok) << s.name;
  EXPECT_EQ(id.stages[0].reason, "bench.csv: cannot read");
  EXPECT_EQ(id.stages[1].reason, "pendulum_x.csv: cannot read");
  EXPECT_EQ(id.stages[2].reason, "attitude_steps.csv: missing column 'yaw'");
  EXPECT_NE(id.stages[3].reason.find("needs the attitude model"), std::string::npos);
  EXPECT_TRUE(id.tables.empty());
  EXPECT_EQ(id.have, (std::vector<std::string>{"mass", "arm_length"}));
  EXPECT_EQ(id.notices.size(), 4U);  // one line per failed stage
  EXPECT_DOUBLE_EQ(id.summary["mass"].get<double>(), 1.2);
  EXPECT_DOUBLE_EQ(id.vehicle.arm_length, 0.2);
}

}  // namespace
}  // namespace fnmpc::sysid
