#include "vehicle_sim/render/scene.h"

#include <gtest/gtest.h>

#include <chrono>
#include <vector>

namespace autodrive::vehicle_sim::internal {
namespace {

using Seconds = std::chrono::duration<double>;

TEST(RenderScene, IndicatorsAreLitTheFirstHalfOfEachPeriodOf1Point5Hz) {
  EXPECT_TRUE(IndicatorsLit(Seconds(0.0)));
  EXPECT_TRUE(IndicatorsLit(Seconds(0.3)));
  EXPECT_FALSE(IndicatorsLit(Seconds(0.34)));
  EXPECT_FALSE(IndicatorsLit(Seconds(0.66)));
  EXPECT_TRUE(IndicatorsLit(Seconds(0.67)));
  EXPECT_FALSE(IndicatorsLit(Seconds(100.0 / 1.5 + 0.4)));
}

// Head ids need not be 1..n: a map may give its heads ids with gaps (docs/maps.md).
TEST(RenderScene, LampsAreSetPerHeadIdAndUnknownHeadsAreIgnored) {
  FrameScene scene({SignalHeadId{2}, SignalHeadId{7}, SignalHeadId{12}});
  const std::vector<HeadLamps> lamps{{SignalHeadId{7}, true, false, true},
                                     {SignalHeadId{12}, false, true, false},
                                     {SignalHeadId{9}, true, true, true},
                                     {SignalHeadId{1}, true, true, true}};
  scene.SetLamps(lamps);
  EXPECT_EQ(scene.lamp_state(), (std::vector<std::uint8_t>{0, 5, 2}));
  scene.SetLamps({});
  EXPECT_EQ(scene.lamp_state(), (std::vector<std::uint8_t>{0, 0, 0}));
}

TEST(RenderScene, TrafficIsDrawnByItsShapeAndAFarObjectIsOneBlockInItsRoofColour) {
  RenderTraffic o;
  o.X_MO.translation() = Eigen::Vector3d(2, 3, 0);
  o.size_m = {4.0, 2.0, 1.5};
  o.body = Rgb{10, 20, 30};
  o.roof = Rgb{40, 50, 60};
  o.brake = true;
  o.left_indicator = true;
  const auto parts_of = [&](TrafficShape shape, bool blink, bool far) {
    FrameScene scene({});
    o.shape = shape;
    scene.AddTraffic(o, blink, far);
    return scene.parts();
  };
  const auto car = parts_of(TrafficShape::kCar, true, false);
  ASSERT_EQ(car.size(), 3u);  // underbody, body, cabin
  EXPECT_EQ(car[1].decal, Decal::kTrafficEnds);
  EXPECT_EQ(car[1].lights, 8 | 2);
  EXPECT_EQ(car[2].colour, o.roof);
  // The parts fill the object's box: the cabin's top is its height.
  EXPECT_NEAR(car[2].p_MB.z() + car[2].half.z(), 1.5, 1e-12);
  EXPECT_EQ(parts_of(TrafficShape::kCar, false, false)[1].lights, 8);
  EXPECT_EQ(parts_of(TrafficShape::kTall, true, false).size(), 2u);
  const auto block = parts_of(TrafficShape::kBlock, true, false);
  ASSERT_EQ(block.size(), 1u);
  EXPECT_EQ(block[0].colour, o.body);
  const auto far = parts_of(TrafficShape::kCar, true, true);
  ASSERT_EQ(far.size(), 1u);
  EXPECT_EQ(far[0].colour, o.roof);
  EXPECT_EQ(far[0].p_MB, Eigen::Vector3d(2, 3, 0.75));
  EXPECT_EQ(far[0].half, Eigen::Vector3d(2.0, 1.0, 0.75));
}

TEST(RenderScene, ClearDropsTheLastFramesPartsAndLamps) {
  FrameScene scene({SignalHeadId{1}});
  RenderTraffic o;
  o.size_m = {1, 1, 1};
  scene.AddTraffic(o, false, true);
  scene.SetLamps(std::vector<HeadLamps>{{SignalHeadId{1}, true, false, false}});
  scene.Clear();
  EXPECT_TRUE(scene.parts().empty());
  EXPECT_EQ(scene.lamp_state(), (std::vector<std::uint8_t>{0}));
}

TEST(RenderScene, ATagBitmapHasTheFamilysSizeAndAnUnknownIdIsAnError) {
  const TagBitmap tag = MakeTagBitmap(TagSpec{"tag36h11", 3, 0.0762});
  EXPECT_EQ(tag.total, 10);
  EXPECT_EQ(tag.at_border, 8);
  ASSERT_EQ(tag.white.size(), 100u);
  // The white border all round, the black one inside it.
  for (int k = 0; k < 10; ++k) {
    EXPECT_EQ(tag.white[static_cast<std::size_t>(k)], 1);
    EXPECT_EQ(tag.white[static_cast<std::size_t>(10 + 1 + (k % 8))], 0);
  }
  try {
    (void)MakeTagBitmap(TagSpec{"tag36h11", 100000, 0.0762});
    FAIL() << "no error for an id tag36h11 does not have";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("100000"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace autodrive::vehicle_sim::internal
