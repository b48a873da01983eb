# Run by find_package(rosidl_default_generators): Debian's rosidl_cmake and generators (each
# registers itself with rosidl_generate_interfaces when found).
find_package(rosidl_cmake REQUIRED)
find_package(rosidl_generator_c REQUIRED)
find_package(rosidl_generator_cpp REQUIRED)
find_package(rosidl_typesupport_introspection_c REQUIRED)
find_package(rosidl_typesupport_introspection_cpp REQUIRED)
