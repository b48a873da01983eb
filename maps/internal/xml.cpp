#include "maps/internal/xml.h"

#include <fmt/format.h>

#include <algorithm>
#include <sstream>

#include "common/error.h"

namespace autodrive::maps::internal {
namespace {

// A character no XML 1.0 document can hold, not even as a character reference: the C0
// controls but tab, line feed and carriage return. (pugixml would write them as "&#1;".)
bool IsForbiddenInXml(char c) {
  const auto u = static_cast<unsigned char>(c);
  return u < 0x20 && c != '\t' && c != '\n' && c != '\r';
}

// The text with its forbidden characters shown as \xNN.
std::string Shown(std::string_view text) {
  std::string out;
  for (char c : text) {
    if (IsForbiddenInXml(c)) {
      out += fmt::format("\\x{:02x}", static_cast<unsigned char>(c));
    } else {
      out += c;
    }
  }
  return out;
}

// Throws InputError when `text` holds a forbidden character; `what` names the text.
void CheckXmlText(std::string_view text, const std::string& what) {
  const auto bad = std::find_if(text.begin(), text.end(), IsForbiddenInXml);
  AUTODRIVE_THROW_UNLESS(bad == text.end(),
                         what << " \"" << Shown(text) << "\" holds the control character "
                              << fmt::format("0x{:02x}", static_cast<unsigned char>(*bad))
                              << ", which XML cannot carry");
}

}  // namespace

void AddXmlDeclaration(pugi::xml_document& doc) {
  pugi::xml_node declaration = doc.append_child(pugi::node_declaration);
  AUTODRIVE_CHECK(declaration && declaration.append_attribute("version").set_value("1.0") &&
                  declaration.append_attribute("encoding").set_value("UTF-8"));
}

void AppendAttribute(pugi::xml_node element, const char* name, std::string_view value) {
  CheckXmlText(value, fmt::format("attribute {} of <{}>", name, element.name()));
  pugi::xml_attribute attribute = element.append_attribute(name);
  AUTODRIVE_CHECK(attribute && attribute.set_value(value.data(), value.size()),
                  "cannot set " << name << " on <" << element.name() << ">");
}

pugi::xml_node AppendElement(pugi::xml_node parent, const char* name,
                             std::initializer_list<XmlAttribute> attributes) {
  // All values are checked first, so that nothing is appended when one is refused.
  for (const auto& [key, value] : attributes) {
    CheckXmlText(value, fmt::format("attribute {} of <{}>", key, name));
  }
  pugi::xml_node element = parent.append_child(name);
  AUTODRIVE_CHECK(element, "cannot append <" << name << ">");
  for (const auto& [key, value] : attributes) {
    pugi::xml_attribute attribute = element.append_attribute(key);
    AUTODRIVE_CHECK(attribute && attribute.set_value(value.data(), value.size()),
                    "cannot set " << key << " on <" << name << ">");
  }
  return element;
}

void SetText(pugi::xml_node element, std::string_view text) {
  CheckXmlText(text, fmt::format("the text of <{}>", element.name()));
  AUTODRIVE_CHECK(element.text().set(text.data(), text.size()),
                  "cannot set the text of <" << element.name() << ">");
}

void AppendComment(pugi::xml_node parent, std::string_view text) {
  AUTODRIVE_CHECK(text.find("--") == std::string_view::npos && !text.ends_with('-') &&
                      std::none_of(text.begin(), text.end(), IsForbiddenInXml),
                  "XML comment \"" << Shown(text) << "\"");
  pugi::xml_node comment = parent.append_child(pugi::node_comment);
  AUTODRIVE_CHECK(comment && comment.set_value(text.data(), text.size()));
}

std::string XmlText(const pugi::xml_document& doc, const char* indent) {
  std::ostringstream out;
  doc.save(out, indent, pugi::format_indent, pugi::encoding_utf8);
  return out.str();
}

}  // namespace autodrive::maps::internal
