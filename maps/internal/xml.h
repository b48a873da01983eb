#pragma once
/// @file
/// XML writing shared by the SUMO exporter (`maps/sumo.cpp`) and the SVG renderer
/// (`maps/render.cpp`): documents are built with pugixml as nodes and attributes, so every
/// value is escaped by the library, and turned into text here in one deterministic format.

#include <initializer_list>
#include <string>
#include <string_view>
#include <utility>

#include <pugixml.hpp>

namespace autodrive::maps::internal {

/// Appends the declaration `<?xml version="1.0" encoding="UTF-8"?>` to `doc` (which should be
/// empty); without one pugixml writes `<?xml version="1.0"?>`.
void AddXmlDeclaration(pugi::xml_document& doc);

/// An attribute to append: its name and its value, as it should read after unescaping.
using XmlAttribute = std::pair<const char*, std::string>;

/// Appends the attribute `name="value"` to `element` (after the ones it has).
/// @throws InputError if `value` holds a character XML cannot carry, escaped or not (a
/// control character other than tab, line feed and carriage return), naming the attribute, the
/// element, the value (control characters shown as `\xNN`) and the character.
void AppendAttribute(pugi::xml_node element, const char* name, std::string_view value);

/// Appends the element `<name>` to `parent` with `attributes`, in their order, and returns it.
/// @throws InputError as `AppendAttribute`; then nothing is appended.
pugi::xml_node AppendElement(pugi::xml_node parent, const char* name,
                             std::initializer_list<XmlAttribute> attributes = {});

/// Sets `text` as the character data of `element` (`<title>a &amp; b</title>`), replacing any.
/// @throws InputError if `text` holds a character XML cannot carry, as `AppendAttribute`.
void SetText(pugi::xml_node element, std::string_view text);

/// Appends the comment `<!--text-->` to `parent`. Precondition (always checked, aborts): the
/// text holds no "--", does not end with '-' (XML forbids both in comments and pugixml would
/// write them as they are) and has no character XML cannot carry.
void AppendComment(pugi::xml_node parent, std::string_view text);

/// The document as UTF-8 text: one node per line, children indented by `indent` per level,
/// an element holding only text on one line, an element without children as `<a x="1" />`,
/// attributes in the order they were appended. pugixml escapes `&`, `<` and `>` in text and
/// `&`, `<`, `"`, tab and line breaks in attributes. The same document always gives the same
/// bytes.
[[nodiscard]] std::string XmlText(const pugi::xml_document& doc, const char* indent);

}  // namespace autodrive::maps::internal
