// introspection_walk: prints ROS 2 message types as rmw_cyclonedds_cpp sees them, from the
// introspection type support that rosidl generated for them (rosidl_typesupport_introspection_c).
// Part of tests/ros2/check_interfaces.py, which compiles it against the installed
// lib<pkg>__rosidl_typesupport_introspection_c.so of every package it walks and turns the output
// into `dds_` IDL.
//
// Usage: introspection_walk pkg/msg/Name [pkg/msg/Name ...]
// Each type's handle comes from the symbol the generated library exports,
// rosidl_typesupport_introspection_c__get_message_type_support_handle__<pkg>__msg__<Name>, looked
// up in the libraries the program is linked with. Output, one line per record, tab-separated:
//   type    <DDS type name> <message_namespace_> <message_name_> <member_count_>
//   member  <name> <type_id_> <nested DDS type name or -> <is_array_> <array_size_>
//           <is_upper_bound_> <string_upper_bound_>
//   end
// The DDS type name follows rmw_cyclonedds_cpp (MessageTypeSupport_impl.hpp, the constructor of
// MessageTypeSupport): the namespace with every "__" replaced by "::", then "::dds_::", the
// name and "_"; e.g. autodrive_msgs__msg + Heartbeat -> autodrive_msgs::msg::dds_::Heartbeat_.
// Exit status: 0, or 1 when a type cannot be found or is not an introspection C type support.

#include <dlfcn.h>
#include <rosidl_runtime_c/message_type_support_struct.h>
#include <rosidl_typesupport_introspection_c/field_types.h>
#include <rosidl_typesupport_introspection_c/message_introspection.h>
#include <stdio.h>
#include <string.h>

#define IDENTIFIER "rosidl_typesupport_introspection_c"
#define SYMBOL_PREFIX "rosidl_typesupport_introspection_c__get_message_type_support_handle__"

typedef const rosidl_message_type_support_t* (*get_handle_function)(void);

// The members of a type support handle, or NULL (with a message) when it is not introspection C.
static const rosidl_typesupport_introspection_c__MessageMembers* members_of(
    const rosidl_message_type_support_t* handle, const char* what) {
  if (handle == NULL || handle->typesupport_identifier == NULL ||
      strcmp(handle->typesupport_identifier, IDENTIFIER) != 0 || handle->data == NULL) {
    fprintf(stderr, "introspection_walk: %s: not a %s type support\n", what, IDENTIFIER);
    return NULL;
  }
  return (const rosidl_typesupport_introspection_c__MessageMembers*)handle->data;
}

// rmw_cyclonedds_cpp's DDS type name of a message type, into out (size bytes).
static int dds_type_name(const rosidl_typesupport_introspection_c__MessageMembers* members,
                         char* out, size_t size) {
  size_t used = 0;
  out[0] = '\0';
  const char* ns = members->message_namespace_;
  if (ns != NULL && ns[0] != '\0') {
    for (const char* c = ns; *c != '\0'; ++c) {
      // std::regex_replace(ns, std::regex("__"), "::"): left to right, non-overlapping.
      if (c[0] == '_' && c[1] == '_') {
        if (used + 2 >= size) return -1;
        out[used++] = ':';
        out[used++] = ':';
        ++c;
      } else {
        if (used + 1 >= size) return -1;
        out[used++] = *c;
      }
    }
    if (used + 2 >= size) return -1;
    out[used++] = ':';
    out[used++] = ':';
  }
  int n = snprintf(out + used, size - used, "dds_::%s_", members->message_name_);
  return (n < 0 || (size_t)n >= size - used) ? -1 : 0;
}

static int walk(const char* type) {
  // "pkg/msg/Name" (or "pkg/Name") -> symbol prefix + "pkg__msg__Name".
  char pkg[256], name[256], symbol[768];
  const char* first = strchr(type, '/');
  const char* last = strrchr(type, '/');
  if (first == NULL || first == type || last[1] == '\0' || (size_t)(first - type) >= sizeof pkg ||
      strlen(last + 1) >= sizeof name) {
    fprintf(stderr, "introspection_walk: %s: expected pkg/msg/Name\n", type);
    return 1;
  }
  memcpy(pkg, type, (size_t)(first - type));
  pkg[first - type] = '\0';
  strcpy(name, last + 1);
  snprintf(symbol, sizeof symbol, "%s%s__msg__%s", SYMBOL_PREFIX, pkg, name);

  void* address = dlsym(RTLD_DEFAULT, symbol);
  if (address == NULL) {
    fprintf(stderr, "introspection_walk: %s: no symbol %s (is its library linked?)\n", type,
            symbol);
    return 1;
  }
  get_handle_function get_handle;
  // A data pointer to a function pointer: what dlsym's interface requires (POSIX).
  memcpy(&get_handle, &address, sizeof get_handle);
  // Calling it also fills in the nested types' handles (members_ of message fields).
  const rosidl_typesupport_introspection_c__MessageMembers* members =
      members_of(get_handle(), type);
  if (members == NULL) return 1;

  char dds_name[1024];
  if (dds_type_name(members, dds_name, sizeof dds_name) != 0) {
    fprintf(stderr, "introspection_walk: %s: type name too long\n", type);
    return 1;
  }
  printf("type\t%s\t%s\t%s\t%u\n", dds_name, members->message_namespace_, members->message_name_,
         (unsigned)members->member_count_);

  for (uint32_t i = 0; i < members->member_count_; ++i) {
    const rosidl_typesupport_introspection_c__MessageMember* m = &members->members_[i];
    char nested[1024] = "-";
    if (m->type_id_ == rosidl_typesupport_introspection_c__ROS_TYPE_MESSAGE) {
      const rosidl_typesupport_introspection_c__MessageMembers* inner =
          members_of(m->members_, m->name_);
      if (inner == NULL || dds_type_name(inner, nested, sizeof nested) != 0) {
        fprintf(stderr, "introspection_walk: %s.%s: no nested type\n", type, m->name_);
        return 1;
      }
    }
    printf("member\t%s\t%u\t%s\t%d\t%zu\t%d\t%zu\n", m->name_, (unsigned)m->type_id_, nested,
           m->is_array_ ? 1 : 0, m->array_size_, m->is_upper_bound_ ? 1 : 0,
           m->string_upper_bound_);
  }
  printf("end\n");
  return 0;
}

int main(int argc, char** argv) {
  if (argc < 2) {
    fprintf(stderr, "usage: %s pkg/msg/Name [pkg/msg/Name ...]\n", argv[0]);
    return 2;
  }
  int failed = 0;
  for (int i = 1; i < argc; ++i) failed |= walk(argv[i]);
  return failed;
}
