#include "maps/internal/xml.h"

#include <gtest/gtest.h>

#include <string>

#include "common/error.h"
#include "common/test_support.h"

namespace autodrive::maps::internal {
namespace {

// Every character XML escapes, and a space and a quote of the other kind.
const std::string kSpecial = "a \"b\" & <c> 'd'";

TEST(XmlText, WritesTheDeclarationOneNodePerLineIndentedAndAttributesInOrder) {
  pugi::xml_document doc;
  AddXmlDeclaration(doc);
  AppendComment(doc, " made by a test ");
  pugi::xml_node root = doc.append_child("edges");
  pugi::xml_node edge = AppendElement(root, "edge", {{"id", "e1"}, {"to", "b"}, {"from", "a"}});
  AppendElement(edge, "lane", {{"index", "0"}});
  AppendAttribute(AppendElement(root, "edge", {{"id", "e2"}}), "shape", "0,0 1,1");
  SetText(root.append_child("note"), "x");
  EXPECT_EQ(XmlText(doc, "    "),
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
            "<!-- made by a test -->\n"
            "<edges>\n"
            "    <edge id=\"e1\" to=\"b\" from=\"a\">\n"
            "        <lane index=\"0\" />\n"
            "    </edge>\n"
            "    <edge id=\"e2\" shape=\"0,0 1,1\" />\n"
            "    <note>x</note>\n"
            "</edges>\n");
}

TEST(XmlText, EscapesAttributesAndTextSoThatTheyParseBackExactly) {
  pugi::xml_document doc;
  AddXmlDeclaration(doc);
  pugi::xml_node root = AppendElement(doc, "svg", {{"name", kSpecial}, {"tabs", "1\t2\n3\r"}});
  SetText(AppendElement(root, "title"), kSpecial);
  const std::string text = XmlText(doc, "  ");
  EXPECT_NE(text.find("name=\"a &quot;b&quot; &amp; &lt;c> 'd'\""), std::string::npos) << text;
  EXPECT_NE(text.find("<title>a \"b\" &amp; &lt;c&gt; 'd'</title>"), std::string::npos) << text;

  pugi::xml_document back;
  const pugi::xml_parse_result result = back.load_string(text.c_str());
  ASSERT_TRUE(result) << result.description();
  EXPECT_EQ(std::string(back.child("svg").attribute("name").value()), kSpecial);
  EXPECT_EQ(std::string(back.child("svg").attribute("tabs").value()), "1\t2\n3\r");
  EXPECT_EQ(std::string(back.child("svg").child("title").text().get()), kSpecial);
}

TEST(XmlText, RefusesControlCharactersThatXmlCannotCarry) {
  pugi::xml_document doc;
  pugi::xml_node root = doc.append_child("nodes");
  EXPECT_EQ(test::ErrorMessage([&] {
              AppendElement(root, "node", {{"id", std::string("a\x01z")}});
            }),
            "attribute id of <node> \"a\\x01z\" holds the control character 0x01, which XML cannot "
            "carry");
  EXPECT_EQ(test::ErrorMessage([&] { SetText(root, std::string("x\x1f y\x02", 5)); }),
            "the text of <nodes> \"x\\x1f y\\x02\" holds the control character 0x1f, which XML "
            "cannot carry");
  EXPECT_EQ(test::ErrorMessage([&] { SetText(root, std::string("nul\0", 4)); }),
            "the text of <nodes> \"nul\\x00\" holds the control character 0x00, which XML cannot "
            "carry");
  EXPECT_TRUE(root.first_child().empty());  // nothing appended
}

}  // namespace
}  // namespace autodrive::maps::internal
