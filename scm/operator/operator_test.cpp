// The operator protocol's replies on the wire: typed values there and back, a value that is not
// JSON refused, and the line for people of each kind of value.
#include "scm/operator/operator.h"

#include <gtest/gtest.h>

#include "autodrive_msgs/msg/OperatorReply.h"

#include "common/dds/message.h"

namespace autodrive::scm {
namespace {

using nlohmann::json;

TEST(Reply, TypedValuesGoOnTheWireAndComeBackTheSame) {
  Reply sent = Reply::Rejected("centre is busy");
  sent.values = {{"lights", json(7)},
                 {"uptime_s", json(12.5)},
                 {"city", json("small_town")},
                 {"centre", json{{"id", 3}, {"latched", nullptr}, {"text", "id=3 mode=auto"}}},
                 {"nothing", json()},
                 {"heads", json::array({"signal_1", "signal_2"})}};
  dds::Message<msg::OperatorReply> wire;
  ReplyToWire(sent, *wire);
  EXPECT_EQ(wire->result, autodrive_msgs_msg_OperatorReply_Constants_REJECTED);
  ASSERT_EQ(wire->values._length, 6u);
  EXPECT_EQ(dds::View(wire->values._buffer[0].value), "7");
  EXPECT_EQ(dds::View(wire->values._buffer[2].value), "\"small_town\"");
  const Reply got = ReplyFromWire(*wire);
  EXPECT_EQ(got.code, ReplyCode::kRejected);
  EXPECT_EQ(got.message, "centre is busy");
  EXPECT_EQ(got.values, sent.values);
  EXPECT_EQ(got.Value("lights"), 7);
  EXPECT_EQ(got.Value("uptime_s"), 12.5);
  EXPECT_EQ(got.Value("centre")["id"], 3);
  EXPECT_TRUE(got.Value("centre")["latched"].is_null());
  EXPECT_TRUE(got.Value("no such key").is_null());
}

TEST(Reply, AValueThatIsNotJsonIsNeverTakenForOne) {
  dds::Message<msg::OperatorReply> wire;
  ReplyToWire(Reply::Ok("1 intersection"), *wire);
  dds::ResizeSequence(wire->values, 1);
  dds::SetString(wire->values._buffer[0].key, "centre");
  dds::SetString(wire->values._buffer[0].value, "id=3 mode=auto");  // an SCM of before
  const Reply got = ReplyFromWire(*wire);
  EXPECT_TRUE(got.Value("centre").is_discarded()) << "no field is guessed from text";
  EXPECT_EQ(ValueText(got.values.at(0).second), "id=3 mode=auto") << "a person still reads it";
}

TEST(Reply, TextThatIsNotUtf8IsRepairedRatherThanThrown) {
  Reply sent = Reply::Ok("ok");
  sent.values = {{"detail", json(std::string("lamp \xff out"))}};
  dds::Message<msg::OperatorReply> wire;
  ReplyToWire(sent, *wire);
  EXPECT_EQ(ReplyFromWire(*wire).Value("detail"), "lamp \xEF\xBF\xBD out");
}

TEST(AppendJsonString, WritesWhatAJsonParserReadsBackTheSame) {
  for (const std::string text : {"", "day", "say \"hi\"", "back\\slash", "tab\there", "line\n",
                                 "\x01", "caf\xc3\xa9", "\x7f"}) {
    SCOPED_TRACE(text);
    std::string out = "[";
    AppendJsonString(text, out);
    out += "]";
    const json parsed = json::parse(out, nullptr, false);
    ASSERT_FALSE(parsed.is_discarded()) << out;
    EXPECT_EQ(parsed[0], text);
  }
  std::string out;
  AppendJsonString("bad \xff byte", out);
  EXPECT_EQ(json::parse(out), "bad \xEF\xBF\xBD byte");
}

TEST(ValueText, StringsAsTheyAreObjectsByTheirTextOthersAsJson) {
  EXPECT_EQ(ValueText(json("small_town")), "small_town");
  EXPECT_EQ(ValueText(json(7)), "7");
  EXPECT_EQ(ValueText(json(12.5)), "12.5");
  EXPECT_EQ(ValueText(json{{"id", 3}, {"text", "id=3 mode=auto"}}), "id=3 mode=auto");
  EXPECT_EQ(ValueText(json{{"id", 3}}), "{\"id\":3}");
  EXPECT_EQ(ValueText(json()), "null");
  // An event: its stamp as a local date-time before its text.
  EXPECT_EQ(ValueText(json{{"stamp", 1795240000.125}, {"text", "alarm x"}}),
            LocalDateTime(1795240000.125) + " alarm x");
}

TEST(LocalDateTime, IsTheLocalDateAndTimeToTheMillisecond) {
  ::setenv("TZ", "UTC", 1);
  ::tzset();
  EXPECT_EQ(LocalDateTime(1795240000.125), "2026-11-21 05:46:40.125");
  EXPECT_EQ(LocalDateTime(1795240000.9996), "2026-11-21 05:46:41.000");
  ::setenv("TZ", "Europe/Berlin", 1);  // CET in November: UTC+1
  ::tzset();
  EXPECT_EQ(LocalDateTime(1795240000.125), "2026-11-21 06:46:40.125");
  ::unsetenv("TZ");
  ::tzset();
}

}  // namespace
}  // namespace autodrive::scm
