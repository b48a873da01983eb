// Checks the messaging contract against ROS 2's conventions:
// - every struct in common/msgs/idl is registered, keyless and final, and its DDS type name is
//   `pkg::msg::dds_::Name_` with `pkg` its folder;
// - the standard types have exactly ROS 2's field layout: the wire layout decoded from the
//   Cyclone topic descriptor (types, order, array bounds, sequences) and the field names in
//   the IDL are compared with ROS 2's .msg definitions, transcribed below.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>

#include "common/dds/messages.h"
#include "common/dds/type_hashes.h"
#include "common/test_support.h"

namespace autodrive::dds {
namespace {

namespace fs = std::filesystem;

// ---- Wire layout from Cyclone's opcodes --------------------------------------------------

std::string Primitive(uint32_t type, uint32_t flags) {
  const bool sgn = flags & DDS_OP_FLAG_SGN;
  const bool fp = flags & DDS_OP_FLAG_FP;
  switch (type) {
    case DDS_OP_VAL_1BY:
      return sgn ? "int8" : "uint8";
    case DDS_OP_VAL_2BY:
      return sgn ? "int16" : "uint16";
    case DDS_OP_VAL_4BY:
      return fp ? "float32" : (sgn ? "int32" : "uint32");
    case DDS_OP_VAL_8BY:
      return fp ? "float64" : (sgn ? "int64" : "uint64");
    case DDS_OP_VAL_BLN:
      return "bool";
    case DDS_OP_VAL_STR:
      return "string";
    default:
      return "";
  }
}

// Decodes the member list of the struct whose ops start at `ops[start]` into a signature such
// as "{{int32,uint32},string}". Throws std::runtime_error on an opcode it does not know, so an
// unexpected layout fails the test instead of passing silently.
std::string Decode(const uint32_t* ops, std::size_t start) {
  std::vector<std::string> members;
  std::size_t i = start;
  for (;;) {
    const uint32_t op = ops[i];
    if (DDS_OP(op) == DDS_OP_RTS) break;
    if (DDS_OP(op) != DDS_OP_ADR) {
      throw std::runtime_error("unexpected opcode " + std::to_string(op >> 24) +
                               " (appendable/mutable types have DLC/PLC; ours are final)");
    }
    const uint32_t type = DDS_OP_TYPE(op);
    const uint32_t sub = DDS_OP_SUBTYPE(op);
    const uint32_t flags = DDS_OP_FLAGS(op);
    if (flags & DDS_OP_FLAG_KEY) throw std::runtime_error("keyed member: ROS types are keyless");
    if (flags & DDS_OP_FLAG_OPT) throw std::runtime_error("optional member: not XCDR1");
    if (const std::string p = Primitive(type, flags); !p.empty()) {
      members.push_back(p);
      i += 2;
    } else if (type == DDS_OP_VAL_EXT) {
      members.push_back(Decode(ops, i + static_cast<std::size_t>(DDS_OP_ADR_JSR(ops[i + 2]))));
      i += 3;
    } else if (type == DDS_OP_VAL_BST) {
      members.push_back("string<=" + std::to_string(ops[i + 2] - 1));
      i += 3;
    } else if (type == DDS_OP_VAL_SEQ || type == DDS_OP_VAL_ARR) {
      const bool seq = type == DDS_OP_VAL_SEQ;
      const std::string suffix = seq ? "[]" : "[" + std::to_string(ops[i + 2]) + "]";
      if (const std::string elem = Primitive(sub, flags); !elem.empty()) {
        members.push_back(elem + suffix);
        i += seq ? 2 : 3;
      } else if (sub == DDS_OP_VAL_STU && seq) {
        members.push_back(Decode(ops, i + static_cast<std::size_t>(DDS_OP_ADR_JSR(ops[i + 3]))) +
                          suffix);
        i += 4;
      } else if (sub == DDS_OP_VAL_STU) {
        members.push_back(Decode(ops, i + static_cast<std::size_t>(DDS_OP_ADR_JSR(ops[i + 3]))) +
                          suffix);
        i += 5;
      } else {
        throw std::runtime_error("unsupported element subtype " + std::to_string(sub));
      }
    } else {
      throw std::runtime_error("unsupported member type " + std::to_string(type));
    }
  }
  std::string s = "{";
  for (std::size_t k = 0; k < members.size(); ++k) s += (k ? "," : "") + members[k];
  return s + "}";
}

std::string WireLayout(const dds_topic_descriptor_t* d) { return Decode(d->m_ops, 0); }

// ---- ROS 2's definitions --------------------------------------------------------------------
// Field lines of the .msg files of ROS 2 (rolling; unchanged since Foxy), comments and
// constants dropped. Nested types are named as in .msg files.
const std::map<std::string, std::string>& RosDefinitions() {
  static const std::map<std::string, std::string> kDefs = {
      {"builtin_interfaces/Time", "int32 sec\nuint32 nanosec"},
      {"builtin_interfaces/Duration", "int32 sec\nuint32 nanosec"},
      {"std_msgs/Header", "builtin_interfaces/Time stamp\nstring frame_id"},
      {"std_msgs/Float32", "float32 data"},
      {"std_msgs/Int32", "int32 data"},
      {"geometry_msgs/Point", "float64 x\nfloat64 y\nfloat64 z"},
      {"geometry_msgs/Vector3", "float64 x\nfloat64 y\nfloat64 z"},
      {"geometry_msgs/Quaternion", "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1"},
      {"geometry_msgs/Pose", "Point position\nQuaternion orientation"},
      {"geometry_msgs/PoseStamped", "std_msgs/Header header\nPose pose"},
      {"geometry_msgs/PoseWithCovariance", "Pose pose\nfloat64[36] covariance"},
      {"geometry_msgs/Twist", "Vector3 linear\nVector3 angular"},
      {"geometry_msgs/TwistWithCovariance", "Twist twist\nfloat64[36] covariance"},
      {"sensor_msgs/Imu",
       "std_msgs/Header header\n"
       "geometry_msgs/Quaternion orientation\nfloat64[9] orientation_covariance\n"
       "geometry_msgs/Vector3 angular_velocity\nfloat64[9] angular_velocity_covariance\n"
       "geometry_msgs/Vector3 linear_acceleration\nfloat64[9] linear_acceleration_covariance"},
      {"sensor_msgs/LaserScan",
       "std_msgs/Header header\nfloat32 angle_min\nfloat32 angle_max\nfloat32 angle_increment\n"
       "float32 time_increment\nfloat32 scan_time\nfloat32 range_min\nfloat32 range_max\n"
       "float32[] ranges\nfloat32[] intensities"},
      {"sensor_msgs/JointState",
       "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\n"
       "float64[] effort"},
      {"sensor_msgs/Image",
       "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n"
       "uint8 is_bigendian\nuint32 step\nuint8[] data"},
      {"rosgraph_msgs/Clock", "builtin_interfaces/Time clock"},
  };
  return kDefs;
}

struct RosField {
  std::string type;  // as written, e.g. "float64[9]", "Point"
  std::string name;
};

std::vector<RosField> RosFields(const std::string& full_name) {
  std::istringstream in(RosDefinitions().at(full_name));
  std::vector<RosField> fields;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream words(line);
    RosField f;
    words >> f.type >> f.name;
    fields.push_back(f);
  }
  return fields;
}

// The signature of a ROS type from its definition, in the same form as `Decode`.
std::string RosLayout(const std::string& full_name) {
  const std::string pkg = full_name.substr(0, full_name.find('/'));
  static const std::set<std::string> kPrimitives = {
      "bool",  "int8",   "uint8",   "int16",   "uint16", "int32", "uint32",
      "int64", "uint64", "float32", "float64", "string", "byte",  "char"};
  std::string s = "{";
  bool first = true;
  for (const auto& f : RosFields(full_name)) {
    std::string base = f.type;
    std::string suffix;
    if (const auto b = base.find('['); b != std::string::npos) {
      suffix = base.substr(b);
      base = base.substr(0, b);
    }
    std::string sig;
    if (kPrimitives.count(base)) {
      sig = base == "byte" || base == "char" ? "uint8" : base;
    } else {
      sig = RosLayout(base.find('/') == std::string::npos ? pkg + "/" + base : base);
    }
    s += (first ? "" : ",") + sig + suffix;
    first = false;
  }
  return s + "}";
}

// ---- Our IDL ----------------------------------------------------------------------------------

fs::path IdlDir() { return test::SourceDir() / "common" / "msgs" / "idl"; }

struct IdlStruct {
  std::string type_name;  // "pkg::msg::dds_::Name_"
  std::vector<std::string> member_names;
  fs::path file;
};

// A small scanner for the IDL subset we write: one `module pkg { module msg { module dds_ {`
// per file and `@final struct Name_ { type name; ... };` blocks.
std::vector<IdlStruct> ScanIdl() {
  std::vector<IdlStruct> out;
  const std::regex struct_re(R"((@\w+\s+)?struct\s+(\w+)\s*\{([^}]*)\};)");
  const std::regex member_re(R"(([\w:<>, ]+?)\s+(\w+)\s*(\[\d+\])?\s*;)");
  for (const auto& entry : fs::recursive_directory_iterator(IdlDir())) {
    if (entry.path().extension() != ".idl") continue;
    std::ifstream in(entry.path());
    std::stringstream text;
    for (std::string line; std::getline(in, line);) {
      text << line.substr(0, line.find("//")) << "\n";  // drop comments
    }
    const std::string body = text.str();
    const std::string pkg = fs::relative(entry.path(), IdlDir()).begin()->string();
    for (std::sregex_iterator it(body.begin(), body.end(), struct_re), end; it != end; ++it) {
      IdlStruct s;
      s.type_name = pkg + "::msg::dds_::" + (*it)[2].str();
      s.file = entry.path();
      if ((*it)[1].str().find("@final") == std::string::npos) {
        ADD_FAILURE() << s.type_name << " in " << s.file << " is not annotated @final";
      }
      const std::string members = (*it)[3].str();
      for (std::sregex_iterator m(members.begin(), members.end(), member_re); m != end; ++m) {
        s.member_names.push_back((*m)[2].str());
      }
      out.push_back(s);
    }
  }
  return out;
}

const dds_topic_descriptor_t* Find(std::string_view type_name) {
  for (const auto* d : AllMessageDescriptors()) {
    if (type_name == d->m_typename) return d;
  }
  return nullptr;
}

// ---- Tests ----------------------------------------------------------------------------------

// The REP-2011 hashes ROS 2 Jazzy publishes for four standard types (the golden values of
// ROS client libraries written by others: rclrs, rclgo, the C and Swift clients), which our
// table, made by scripts/generate-type-hashes from the vendored upstream .msg, must reproduce.
TEST(TypeHashes, ReproduceTheHashesRos2Publishes) {
  EXPECT_EQ(TypeHash("builtin_interfaces::msg::dds_::Time_"),
            "RIHS01_b106235e25a4c5ed35098aa0a61a3ee9c9b18d197f398b0e4206cea9acf9c197");
  EXPECT_EQ(TypeHash("std_msgs::msg::dds_::Header_"),
            "RIHS01_f49fb3ae2cf070f793645ff749683ac6b06203e41c891e17701b1cb597ce6a01");
  EXPECT_EQ(TypeHash("geometry_msgs::msg::dds_::Vector3_"),
            "RIHS01_cc12fe83e4c02719f1ce8070bfd14aecd40f75a96696a67a2a1f37f7dbb0765d");
  EXPECT_EQ(TypeHash("geometry_msgs::msg::dds_::Quaternion_"),
            "RIHS01_8a765f66778c8ff7c8ab94afcc590a2ed5325a1d9a076ffff38fbce36f458684");
}

TEST(TypeHashes, EveryRegisteredTypeHasOneAndOthersNone) {
  const std::regex rihs01("^RIHS01_[0-9a-f]{64}$");
  std::set<std::string_view> seen;
  for (const auto* d : AllMessageDescriptors()) {
    SCOPED_TRACE(d->m_typename);
    const std::string_view hash = TypeHash(d->m_typename);
    EXPECT_TRUE(std::regex_match(std::string(hash), rihs01)) << hash;
    EXPECT_TRUE(seen.insert(hash).second) << "two types with one hash";
    EXPECT_EQ(EndpointUserData(d->m_typename), "typehash=" + std::string(hash) + ";");
  }
  EXPECT_EQ(TypeHash("std_msgs::msg::dds_::Header"), "");  // not a DDS type name
  EXPECT_EQ(TypeHash("nobody_msgs::msg::dds_::Nothing_"), "");
  EXPECT_EQ(EndpointUserData("nobody_msgs::msg::dds_::Nothing_"), "typehash=;");
}

TEST(MessageTypes, EveryIdlStructIsRegisteredAndNothingElse) {
  const auto structs = ScanIdl();
  ASSERT_GE(structs.size(), 40u);
  std::set<std::string> in_idl;
  for (const auto& s : structs) in_idl.insert(s.type_name);
  std::set<std::string> registered;
  for (const auto* d : AllMessageDescriptors()) registered.insert(d->m_typename);
  EXPECT_EQ(in_idl, registered);
}

TEST(MessageTypes, TypeNamesFollowRos2ConventionsAndTypesAreKeylessAndFinal) {
  const std::regex name_re("^([a-z][a-z0-9_]*)::msg::dds_::([A-Z][A-Za-z0-9]*)_$");
  for (const auto* d : AllMessageDescriptors()) {
    SCOPED_TRACE(d->m_typename);
    std::cmatch m;
    ASSERT_TRUE(std::regex_match(d->m_typename, m, name_re));
    EXPECT_EQ(d->m_nkeys, 0u) << "ROS 2 types are keyless";
    EXPECT_NO_THROW((void)WireLayout(d));  // only final, XCDR1-compatible members
  }
  for (const auto& s : ScanIdl()) {
    // One message per file, named after the file, as rosidl lays packages out; the folder is
    // the package. (Several constants modules may share it.)
    const std::string file_stem = s.file.stem().string();
    const std::string pkg = s.file.parent_path().parent_path().filename().string();
    EXPECT_EQ(s.type_name, pkg + "::msg::dds_::" + file_stem + "_") << s.file;
    EXPECT_EQ(s.file.parent_path().filename(), "msg") << s.file;
  }
}

TEST(MessageTypes, StandardTypesHaveRos2sWireLayout) {
  for (const auto& [full_name, definition] : RosDefinitions()) {
    SCOPED_TRACE(full_name);
    const std::string pkg = full_name.substr(0, full_name.find('/'));
    const std::string name = full_name.substr(full_name.find('/') + 1);
    const auto* d = Find(pkg + "::msg::dds_::" + name + "_");
    ASSERT_NE(d, nullptr) << "standard type not in the contract";
    EXPECT_EQ(WireLayout(d), RosLayout(full_name));
  }
}

TEST(MessageTypes, StandardTypesHaveRos2sFieldNames) {
  const auto structs = ScanIdl();
  for (const auto& [full_name, definition] : RosDefinitions()) {
    SCOPED_TRACE(full_name);
    const std::string pkg = full_name.substr(0, full_name.find('/'));
    const std::string type_name = pkg + "::msg::dds_::" + full_name.substr(pkg.size() + 1) + "_";
    const auto it = std::find_if(structs.begin(), structs.end(),
                                 [&](const IdlStruct& s) { return s.type_name == type_name; });
    ASSERT_NE(it, structs.end());
    std::vector<std::string> ros_names;
    for (const auto& f : RosFields(full_name)) ros_names.push_back(f.name);
    EXPECT_EQ(it->member_names, ros_names);
  }
}

// The decoder itself is checked on layouts written out by hand, so that a bug in it cannot
// make the comparison above pass vacuously.
TEST(MessageTypes, LayoutDecoderReadsKnownTypesExactly) {
  EXPECT_EQ(WireLayout(&std_msgs_msg_dds__Header__desc), "{{int32,uint32},string}");
  EXPECT_EQ(WireLayout(&sensor_msgs_msg_dds__Image__desc),
            "{{{int32,uint32},string},uint32,uint32,string,uint8,uint32,uint8[]}");
  EXPECT_EQ(WireLayout(&geometry_msgs_msg_dds__PoseWithCovariance__desc),
            "{{{float64,float64,float64},{float64,float64,float64,float64}},float64[36]}");
  EXPECT_EQ(WireLayout(&autodrive_msgs_msg_dds__MapConnection__desc),
            "{uint32,uint32,uint8,uint32,{float64,float64,float64}[]}");
  EXPECT_EQ(RosLayout("geometry_msgs/Pose"),
            "{{float64,float64,float64},{float64,float64,float64,float64}}");
  EXPECT_NE(WireLayout(&geometry_msgs_msg_dds__Point__desc), RosLayout("geometry_msgs/Quaternion"));
}

TEST(MessageTypes, AliasesNameTheGeneratedTypes) {
  EXPECT_EQ(TypeName<msg::LaserScan>(), "sensor_msgs::msg::dds_::LaserScan_");
  EXPECT_EQ(TypeName<msg::Clock>(), "rosgraph_msgs::msg::dds_::Clock_");
  EXPECT_EQ(TypeName<msg::Spat>(), "autodrive_msgs::msg::dds_::Spat_");
  EXPECT_EQ(TypeName<msg::Time>(), "builtin_interfaces::msg::dds_::Time_");
}

}  // namespace
}  // namespace autodrive::dds
