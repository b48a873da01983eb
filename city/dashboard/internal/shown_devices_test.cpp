#include "city/dashboard/internal/shown_devices.h"

#include <gtest/gtest.h>

#include "common/dds/message.h"
#include "common/dds/messages.h"

namespace autodrive::dashboard::internal {
namespace {

/// A reported light's row of the SCM's device table.
dds::Message<msg::DeviceEntry> Light(const char* id) {
  dds::Message<msg::DeviceEntry> d;
  dds::SetString(d->device_id, id);
  dds::SetString(d->host, "lights_east");
  dds::SetString(d->detail, "ok");
  d->kind = autodrive_msgs_msg_DeviceStatus_Constants_TRAFFIC_LIGHT;
  d->health = 1;
  d->reported = true;
  return d;
}

TEST(DashboardShownDevices, ARowIsChangedWhenNewOrWhenWhatThePageShowsOfItChanged) {
  ShownDevices shown;
  auto a = Light("signal_1");
  EXPECT_TRUE(shown.Changed(*a));
  EXPECT_FALSE(shown.Changed(*a));

  // What the page does not compare: the time of the last report.
  a->last_report.sec += 1;
  EXPECT_FALSE(shown.Changed(*a));

  a->health = 2;
  EXPECT_TRUE(shown.Changed(*a));
  EXPECT_FALSE(shown.Changed(*a));
  dds::SetString(a->detail, "red lamp out");
  EXPECT_TRUE(shown.Changed(*a));
  dds::SetString(a->host, "lights_west");
  EXPECT_TRUE(shown.Changed(*a));
  a->lost = true;
  EXPECT_TRUE(shown.Changed(*a));
  a->mode = autodrive_msgs_msg_DeviceStatus_Constants_FLASH;
  EXPECT_TRUE(shown.Changed(*a));
  EXPECT_FALSE(shown.Changed(*a));

  // Each device by its own id: another's first row is new, and leaves the first one's as it was.
  const auto b = Light("signal_2");
  EXPECT_TRUE(shown.Changed(*b));
  EXPECT_FALSE(shown.Changed(*a));
  EXPECT_FALSE(shown.Changed(*b));
}

}  // namespace
}  // namespace autodrive::dashboard::internal
