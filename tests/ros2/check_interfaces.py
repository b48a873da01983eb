#!/usr/bin/python3
"""Checks that the project's DDS types are ROS 2's, as rmw_cyclonedds_cpp puts them on the wire.

The platform compiles its IDL (common/msgs/idl) with Cyclone's idlc; a ROS 2 node on
rmw_cyclonedds_cpp gets its types from rosidl's introspection type support instead, and the two
only meet on the wire. This check builds the ROS side with ROS's own tools (Debian's colcon,
ament_cmake and rosidl) and compares, independently of scripts/generate-msg-idl:

  a. In a temporary workspace (--work, or a fresh temporary folder; nothing is written into the
     source tree): colcon builds the vendored upstream packages (tests/ros2/upstream: Jazzy's
     builtin_interfaces, std_msgs, geometry_msgs, sensor_msgs, rosgraph_msgs, rmw_dds_common)
     and the two stand-ins Debian lacks (tests/ros2/standins). Then, with their install
     sourced, the `colcon build` line of ros2/autodrive_msgs/README.md (the fenced sh block
     after `<!-- ci: colcon -->`) runs verbatim in a workspace whose
     src/autodrive_smart_city/ros2 is a copy of the repository's ros2/. The install must have
     autodrive_msgs' generator_c and introspection C/C++ libraries and every .msg and .idl.
  b. introspection_walk.c, compiled against every package's installed introspection C library,
     prints each type's DDS name by rmw_cyclonedds' rule (pkg::msg::dds_::Name_) and its members
     as rmw_cyclonedds reads them. From that (and the constants of rosidl's own IDL of the type)
     the check writes a "derived" IDL in the project's `dds_` form.
  c. For every type: the name the project registers (idlc's m_typename) equals the derived one;
     idlc's output (.c and .h, after the banner that names file paths) for the derived IDL equals
     idlc's output for the project's; every constant of rosidl's C headers equals idlc's #define.

--self-test then mutates a copy of the project's IDL three times (two adjacent fields swapped, a
bound added, a constant changed) and fails unless step c reports each one.

Run with Debian's Python (/usr/bin/python3: a pyenv python3 on PATH has no rosidl). Exit status
0 when everything matches, 1 on a difference or a failed step, 2 on a usage or set-up error.
"""

import argparse
import difflib
import importlib
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
PACKAGE = "autodrive_msgs"
# The vendored upstream interface packages, in no particular order (colcon orders the build).
VENDORED = ("builtin_interfaces", "std_msgs", "geometry_msgs", "sensor_msgs", "rosgraph_msgs",
            "rmw_dds_common")
# Walked and turned into IDL, but the project has no IDL of its own for them (yet).
DERIVED_ONLY = {"rmw_dds_common"}
STANDINS = ("rosidl_default_generators", "rosidl_default_runtime")
README_MARKER = "<!-- ci: colcon -->"
# Used only while ros2/autodrive_msgs/README.md does not exist.
FALLBACK_COLCON_LINE = (
    "colcon build --base-paths src/autodrive_smart_city/ros2 --packages-select autodrive_msgs")
DEBIAN_PACKAGES = ("python3-rosidl python3-ament-index rosidl-cmake rosidl-generator-c-cpp "
                   "librosidl-typesupport-introspection-c-cpp-dev ament-cmake colcon "
                   "python3-colcon-ros python3-colcon-cmake python3-colcon-bash "
                   "python3-colcon-output python3-colcon-package-selection")
MARKER_FILE = ".check_interfaces_work"

# rosidl_typesupport_introspection_c's field type ids (field_types.h) as IDL types.
IDL_OF_TYPE_ID = {
    1: "float", 2: "double", 3: "long double", 4: "char", 5: "wchar", 6: "boolean", 7: "octet",
    8: "uint8", 9: "int8", 10: "uint16", 11: "int16", 12: "uint32", 13: "int32", 14: "uint64",
    15: "int64", 16: "string", 17: "wstring",
}
TYPE_ID_MESSAGE = 18


class CheckError(Exception):
    """A step that cannot go on; the message says why."""


def log(message=""):
    print(message, flush=True)


# --- environment and processes -----------------------------------------------------------------

def check_prerequisites(args):
    """Everything the check needs, with the Debian package to install for each missing piece."""
    problems = []
    try:
        importlib.import_module("rosidl_parser.parser")
    except ImportError as error:
        problems.append(
            f"{sys.executable} cannot import rosidl_parser ({error}): run this with Debian's "
            "/usr/bin/python3 and install python3-rosidl")
    needed_files = {
        "/usr/share/ament_cmake/cmake/ament_cmakeConfig.cmake": "ament-cmake",
        "/usr/share/rosidl_cmake/cmake/rosidl_cmakeConfig.cmake": "rosidl-cmake",
        "/usr/share/rosidl_generator_c/cmake/rosidl_generator_cConfig.cmake":
            "rosidl-generator-c-cpp",
        "/usr/include/rosidl_typesupport_introspection_c/rosidl_typesupport_introspection_c/"
        "message_introspection.h": "librosidl-typesupport-introspection-c-cpp-dev",
    }
    for path, package in needed_files.items():
        if not Path(path).exists():
            problems.append(f"missing {path}: install {package}")
    if shutil.which("colcon", path="/usr/bin:/bin:" + os.environ.get("PATH", "")) is None:
        problems.append("no colcon: install colcon python3-colcon-ros python3-colcon-cmake "
                        "python3-colcon-bash")
    # Modules of Debian's python3 that colcon, ament_cmake and rosidl import.
    if not Path("/usr/bin/python3").exists():
        problems.append("no /usr/bin/python3: install python3")
    for module, package in (("colcon_ros", "python3-colcon-ros"),
                            ("colcon_cmake", "python3-colcon-cmake"),
                            ("colcon_bash", "python3-colcon-bash"),
                            ("colcon_package_selection", "python3-colcon-package-selection"),
                            ("ament_package", "python3-ament-package"),
                            ("ament_index_python", "python3-ament-index")):
        found = Path("/usr/bin/python3").exists() and subprocess.run(
            ["/usr/bin/python3", "-c", f"import {module}"], stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL).returncode == 0
        if not found:
            problems.append(f"Debian's python3 has no {module}: install {package}")
    if shutil.which(args.idlc) is None:
        problems.append(f"no idlc at '{args.idlc}': install cyclonedds-tools or pass --idlc")
    if shutil.which(args.cc) is None:
        problems.append(f"no C compiler '{args.cc}': pass --cc")
    if problems:
        raise CheckError("missing prerequisites:\n  - " + "\n  - ".join(problems) +
                         f"\nThe Debian packages this check needs: {DEBIAN_PACKAGES}")


def base_environment(work):
    """The environment for colcon: Debian's Python first on PATH (ament's CMake and rosidl's
    generator scripts find `python3` there), one job at a time, no ROS or colcon set-up of the
    caller's (a sourced ROS would bring the real rosidl_default_generators)."""
    env = dict(os.environ)
    for name in ("AMENT_PREFIX_PATH", "COLCON_PREFIX_PATH", "CMAKE_PREFIX_PATH", "PYTHONPATH",
                 "ROS_DISTRO", "ROS_VERSION", "CMAKE_GENERATOR", "COLCON_DEFAULTS_FILE"):
        env.pop(name, None)
    env["PATH"] = "/usr/bin:/bin:" + os.environ.get("PATH", "")
    env["MAKEFLAGS"] = "-j1"
    env["CMAKE_BUILD_PARALLEL_LEVEL"] = "1"
    # An empty colcon home: no defaults.yaml or mixins of the caller's.
    env["COLCON_HOME"] = str(work / "colcon_home")
    (work / "colcon_home").mkdir(exist_ok=True)
    return env


def sourced_environment(env, setup_files):
    """The environment after `source`-ing colcon's setup.bash files in bash, in order."""
    script = " && ".join(f'source "{path}"' for path in setup_files) + " && env -0"
    result = subprocess.run(["bash", "-c", script], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    if result.returncode != 0:
        raise CheckError(f"sourcing {', '.join(map(str, setup_files))} failed:\n"
                         + result.stderr.decode(errors="replace"))
    sourced = {}
    for entry in result.stdout.split(b"\0"):
        if b"=" in entry:
            name, value = entry.decode(errors="replace").split("=", 1)
            sourced[name] = value
    # Debian's python3 stays first (the sourced scripts may have put their bin/ first).
    sourced["PATH"] = "/usr/bin:/bin:" + sourced.get("PATH", "")
    return sourced


def run_logged(command, cwd, env, log_file, shell=False):
    """Runs a command with its output into log_file, showing colcon's progress lines; returns
    (exit status, seconds)."""
    start = time.monotonic()
    with open(log_file, "w") as out:
        process = subprocess.Popen(["bash", "-c", command] if shell else command, cwd=cwd,
                                   env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                   text=True, errors="replace")
        for line in process.stdout:
            out.write(line)
            if line.startswith(("Starting >>>", "Finished <<<", "Failed", "Aborted", "Summary",
                                "WARNING:colcon")):
                log("    " + line.rstrip())
        status = process.wait()
    return status, time.monotonic() - start


def tail(path, lines=40):
    text = Path(path).read_text(errors="replace").splitlines()
    return "\n".join("    | " + line for line in text[-lines:])


# --- step a: the colcon builds -----------------------------------------------------------------

def prepare_work(args):
    """The work folder: a fresh temporary one, or --work emptied (only if it is ours)."""
    if args.work is None:
        work = Path(tempfile.mkdtemp(prefix="ros2_interfaces_"))
    else:
        work = Path(args.work).resolve()
        source = args.source.resolve()
        if work == source or source in work.parents and not str(work).startswith(
                str(source / "build")):
            raise CheckError(f"--work {work} is inside the source tree {source}: choose a "
                             "folder elsewhere (a build folder is fine)")
        if work.exists() and any(work.iterdir()):
            if not (work / MARKER_FILE).exists():
                raise CheckError(f"--work {work} is not empty and was not made by this check: "
                                 "refusing to empty it")
            # Everything goes, but for the colcon workspaces when they are to be reused.
            keep = {"deps", "ws", "logs", "colcon_home"} if args.reuse_build else set()
            for entry in work.iterdir():
                if entry.name in keep:
                    continue
                if entry.is_dir() and not entry.is_symlink():
                    shutil.rmtree(entry)
                else:
                    entry.unlink()
        elif args.reuse_build:
            raise CheckError(f"--reuse-build: {work} holds no earlier run")
    work.mkdir(parents=True, exist_ok=True)
    (work / MARKER_FILE).write_text("A work folder of tests/ros2/check_interfaces.py; "
                                    "it empties it at each run.\n")
    (work / "logs").mkdir(exist_ok=True)
    return work


def readme_colcon_lines(source):
    """The `colcon build` lines of ros2/autodrive_msgs/README.md's block marked for CI."""
    readme = source / "ros2" / PACKAGE / "README.md"
    if not readme.exists():
        log(f"  NOTE: {readme} does not exist: using the fallback line `{FALLBACK_COLCON_LINE}`")
        return [FALLBACK_COLCON_LINE]
    lines = readme.read_text().splitlines()
    for index, line in enumerate(lines):
        if line.strip() != README_MARKER:
            continue
        if index + 1 >= len(lines) or lines[index + 1].strip() not in ("```sh", "```bash"):
            raise CheckError(f"{readme}:{index + 1}: `{README_MARKER}` must be followed directly "
                             "by a ```sh block")
        block = []
        for inner in lines[index + 2:]:
            if inner.strip().startswith("```"):
                break
            block.append(inner.strip())
        else:
            raise CheckError(f"{readme}:{index + 2}: the ```sh block is not closed")
        commands = [entry for entry in block if entry.startswith("colcon build")]
        if not commands:
            raise CheckError(f"{readme}:{index + 2}: the block after `{README_MARKER}` has no "
                             "`colcon build` line")
        return commands
    raise CheckError(f"{readme}: no `{README_MARKER}` line before the build command's block")


def package_prefix(install, package):
    """A package's install prefix: colcon's isolated layout or a merged one."""
    for prefix in (install / package, install):
        if (prefix / "share" / package / "package.xml").exists():
            return prefix
    return None


def build_workspaces(work, source, env):
    """Step a: builds the vendored packages and stand-ins, then autodrive_msgs by the README's
    command; returns {package: install prefix}, the sourced environment and the timings."""
    deps = work / "deps"
    for folder in ("upstream", "standins"):
        for package in sorted((HERE / folder).iterdir()):
            if (package / "package.xml").exists():
                shutil.copytree(package, deps / "src" / package.name)
    log("a. colcon build of the vendored upstream packages and the stand-ins "
        f"(in {deps}, sequential, -j1)")
    command = ["colcon", "build", "--executor", "sequential", "--base-paths", "src",
               "--cmake-args", "-DBUILD_TESTING=OFF", "-DPython3_EXECUTABLE=/usr/bin/python3"]
    status, deps_seconds = run_logged(command, deps, env, work / "logs" / "colcon_deps.log")
    if status != 0:
        raise CheckError(f"colcon build of the vendored packages failed (status {status}); "
                         f"last lines of {work / 'logs' / 'colcon_deps.log'}:\n"
                         + tail(work / "logs" / "colcon_deps.log"))
    log(f"   {len(VENDORED) + len(STANDINS)} packages built in {deps_seconds:.1f} s")
    deps_env = sourced_environment(env, [deps / "install" / "setup.bash"])

    ws = work / "ws"
    shutil.copytree(source / "ros2", ws / "src" / "autodrive_smart_city" / "ros2",
                    ignore=shutil.ignore_patterns("__pycache__"))
    lines = readme_colcon_lines(source)
    ws_seconds = 0.0
    for number, line in enumerate(lines):
        log(f"a. in {ws}, the README's line, verbatim: {line}")
        log_file = work / "logs" / f"colcon_ws_{number}.log"
        status, seconds = run_logged(line, ws, deps_env, log_file, shell=True)
        ws_seconds += seconds
        if status != 0:
            raise CheckError(f"`{line}` failed (status {status}); last lines of {log_file}:\n"
                             + tail(log_file))
    log(f"   built in {ws_seconds:.1f} s")

    prefixes = {name: deps / "install" / name for name in VENDORED}
    prefix = package_prefix(ws / "install", PACKAGE)
    if prefix is None:
        raise CheckError(f"the README's command installed no {PACKAGE} under {ws / 'install'} "
                         f"(did colcon find the package? see {work / 'logs'})")
    check_install(prefix, source)
    prefixes[PACKAGE] = prefix
    final_env = sourced_environment(env, [deps / "install" / "setup.bash",
                                          ws / "install" / "setup.bash"])
    return prefixes, final_env, deps_seconds, ws_seconds


def check_install(prefix, source):
    """autodrive_msgs' install has its libraries and every .msg and .idl."""
    missing = []
    for library in ("rosidl_generator_c", "rosidl_typesupport_introspection_c",
                    "rosidl_typesupport_introspection_cpp"):
        path = prefix / "lib" / f"lib{PACKAGE}__{library}.so"
        if not path.exists():
            missing.append(str(path))
    for msg in sorted((source / "ros2" / PACKAGE / "msg").glob("*.msg")):
        for suffix in (".msg", ".idl"):
            path = prefix / "share" / PACKAGE / "msg" / (msg.stem + suffix)
            if not path.exists():
                missing.append(str(path))
    if missing:
        raise CheckError(f"the install of {PACKAGE} lacks:\n  " + "\n  ".join(missing))
    log(f"   {prefix}: the 3 libraries and every .msg and .idl are installed")


# --- step b: the walk and the derived IDL ------------------------------------------------------

def ros_types(prefixes):
    """Every message type installed by the walked packages, as pkg/msg/Name."""
    names = []
    for package, prefix in sorted(prefixes.items()):
        names += [f"{package}/msg/{msg.stem}"
                  for msg in sorted((prefix / "share" / package / "msg").glob("*.msg"))]
    return names


def walk_types(work, prefixes, env, cc):
    """Step b: compiles introspection_walk.c against the installed introspection C libraries,
    runs it on every type; returns {pkg/msg/Name: walked type}."""
    walk_dir = work / "walk"
    walk_dir.mkdir(exist_ok=True)
    program = walk_dir / "introspection_walk"
    command = [cc, "-std=c11", "-Wall", "-o", str(program), str(HERE / "introspection_walk.c")]
    for include in ("rosidl_runtime_c", "rosidl_typesupport_interface",
                    "rosidl_typesupport_introspection_c", "rcutils"):
        if Path("/usr/include", include).is_dir():
            command.append(f"-I/usr/include/{include}")
    # Linked whether or not a symbol is referenced (the walker finds them with dlsym), and with a
    # DT_RPATH, which (unlike DT_RUNPATH) also serves the libraries' own dependencies.
    command += ["-Wl,--no-as-needed", "-Wl,--disable-new-dtags"]
    for package, prefix in sorted(prefixes.items()):
        command += [f"-L{prefix / 'lib'}", f"-Wl,-rpath,{prefix / 'lib'}",
                    f"-l{package}__rosidl_typesupport_introspection_c"]
    command += ["-ldl"]
    compiled = subprocess.run(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                              text=True)
    if compiled.returncode != 0:
        raise CheckError("compiling introspection_walk.c failed:\n  " + " ".join(command) +
                         "\n" + compiled.stdout)
    types = ros_types(prefixes)
    walked = subprocess.run([str(program)] + types, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    (walk_dir / "walk.txt").write_text(walked.stdout)
    if walked.returncode != 0:
        raise CheckError("introspection_walk failed:\n" + walked.stderr)
    result = parse_walk(walked.stdout, types)
    log(f"b. introspection_walk: {len(result)} types from {len(prefixes)} packages "
        f"({walk_dir / 'walk.txt'})")
    return result


def parse_walk(text, requested):
    """The walker's records, keyed by the pkg/msg/Name they were asked for, in order."""
    walked = {}
    current = None
    names = iter(requested)
    for line in text.splitlines():
        fields = line.split("\t")
        if fields[0] == "type":
            current = {"dds_name": fields[1], "namespace": fields[2], "name": fields[3],
                       "members": []}
            walked[next(names)] = current
        elif fields[0] == "member":
            current["members"].append({
                "name": fields[1], "type_id": int(fields[2]),
                "nested": None if fields[3] == "-" else fields[3],
                "is_array": fields[4] == "1", "array_size": int(fields[5]),
                "is_upper_bound": fields[6] == "1", "string_upper_bound": int(fields[7])})
    if len(walked) != len(requested):
        raise CheckError(f"introspection_walk printed {len(walked)} of {len(requested)} types")
    return walked


def rosidl_constants(prefix, key):
    """The constants of rosidl's own IDL of a type (share/<pkg>/msg/Name.idl, which rosidl_adapter
    made from the .msg) as (IDL type, name, IDL literal), in order."""
    from rosidl_parser import definition
    from rosidl_parser.parser import parse_idl_file
    package, _, name = key.split("/")
    idl = parse_idl_file(definition.IdlLocator(prefix / "share" / package, f"msg/{name}.idl"))
    messages = idl.content.get_elements_of_type(definition.Message)
    constants = []
    for constant in messages[0].constants:
        kind = constant.type
        if isinstance(kind, definition.BasicType):
            type_name = kind.typename
        elif isinstance(kind, (definition.BoundedString, definition.BoundedWString)):
            base = "string" if isinstance(kind, definition.BoundedString) else "wstring"
            type_name = f"{base}<{kind.maximum_size}>"
        elif isinstance(kind, definition.AbstractWString):
            type_name = "wstring"
        else:
            type_name = "string"
        value = constant.value
        if isinstance(value, bool):
            literal = "TRUE" if value else "FALSE"
        elif isinstance(value, str):
            literal = '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
        else:
            literal = repr(value)
        constants.append((type_name, constant.name, literal))
    return constants


def idl_member(member):
    """One member of a walked type as an IDL declaration, as rmw_cyclonedds reads it: a fixed
    array when is_array_ with a size and no upper bound, a bounded sequence when is_upper_bound_,
    an unbounded sequence otherwise (TypeSupport_impl.hpp)."""
    if member["type_id"] == TYPE_ID_MESSAGE:
        base = member["nested"]
    else:
        base = IDL_OF_TYPE_ID[member["type_id"]]
        if base in ("string", "wstring") and member["string_upper_bound"] > 0:
            base += f"<{member['string_upper_bound']}>"
    name = member["name"]
    if not member["is_array"]:
        return f"{base} {name};"
    if member["array_size"] > 0 and not member["is_upper_bound"]:
        return f"{base} {name}[{member['array_size']}];"
    if member["is_upper_bound"]:
        return f"sequence<{base}, {member['array_size']}> {name};"
    return f"sequence<{base}> {name};"


def idl_path_of(dds_name):
    """pkg::msg::dds_::Name_ -> pkg/msg/Name.idl"""
    parts = dds_name.split("::")
    return "/".join(parts[:-2]) + "/" + parts[-1][:-1] + ".idl"


def write_derived_idl(work, walked, prefixes):
    """Step b: one IDL file per walked type, in the project's `dds_` form; returns its root and
    {pkg/msg/Name: constants}."""
    root = work / "derived_idl"
    constants_of = {}
    for key, kind in walked.items():
        package = key.split("/")[0]
        constants = rosidl_constants(prefixes[package], key)
        constants_of[key] = constants
        modules = kind["namespace"].split("__")  # e.g. autodrive_msgs__msg
        name = kind["name"]
        guard = "DERIVED__" + "__".join(m.upper() for m in modules) + f"__{name.upper()}__IDL"
        lines = [f"// {key}",
                 "// Derived by tests/ros2/check_interfaces.py: the members from rosidl's",
                 "// introspection type support (as rmw_cyclonedds_cpp reads them), the constants",
                 "// from rosidl's IDL of the type.",
                 f"#ifndef {guard}", f"#define {guard}"]
        included = []
        for member in kind["members"]:
            nested = member["nested"]
            if nested and nested != kind["dds_name"] and nested not in included:
                included.append(nested)
        lines += [f'#include "{idl_path_of(nested)}"' for nested in included]
        lines.append(" ".join(f"module {m} {{" for m in modules))
        if constants:
            lines.append(f"module {name}_Constants {{")
            lines += [f"  const {t} {n} = {v};" for t, n, v in constants]
            lines.append("};")
        lines += ["module dds_ {", f"@final struct {name}_ {{"]
        lines += ["  " + idl_member(member) for member in kind["members"]]
        lines += ["};", "};", " ".join("};" for _ in modules), f"#endif  // {guard}", ""]
        path = root / (key + ".idl")
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("\n".join(lines))
    log(f"b. derived IDL of {len(walked)} types in {root}")
    return root, constants_of


# --- step c: the comparison --------------------------------------------------------------------

def strip_banner(text):
    """idlc's output without its leading comment (it names the output and source paths)."""
    lines = text.splitlines()
    if lines and lines[0].startswith("/*"):
        for index, line in enumerate(lines):
            if line.rstrip().endswith("*/"):
                return lines[index + 1:]
    return lines


def idlc_outputs(idlc, root, out_dir):
    """Compiles every IDL file under root as the project's build does (idlc -x final -I root -b
    root -o OUT); returns {pkg/msg/Name: (.c lines, .h lines) or an error string}.
    idlc runs in out_dir with the relative output folder `gen`, so that the include guards it
    derives from the output path are the same for every tree compiled this way."""
    if out_dir.exists():
        shutil.rmtree(out_dir)
    out_dir.mkdir(parents=True)
    outputs = {}
    for idl in sorted(root.rglob("*.idl")):
        key = idl.relative_to(root).with_suffix("").as_posix()
        result = subprocess.run([idlc, "-x", "final", "-I", str(root), "-b", str(root), "-o",
                                 "gen", str(idl)], cwd=out_dir, stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True)
        if result.returncode != 0:
            outputs[key] = f"idlc failed on {idl}:\n{result.stdout}"
            continue
        outputs[key] = tuple(strip_banner((out_dir / "gen" / (key + suffix)).read_text())
                             for suffix in (".c", ".h"))
    return outputs


def c_value(text):
    """A constant's value as C source writes it, as a Python value (rosidl_generator_c writes
    1ul, 2ull, -3ll, 0.5f, 0.5l, (-2147483647l - 1), true, "s"; idlc writes 1, 0.500000, true,
    ("s"), ('c'))."""
    text = text.strip()
    while text.startswith("(") and text.endswith(")"):
        text = text[1:-1].strip()
    folded = re.fullmatch(r"\(?(-?\d+)[uUlL]*\s*-\s*1\)?", text)
    if folded:
        return int(folded.group(1)) - 1
    if text in ("true", "false"):
        return text == "true"
    if text.startswith('"') or text.startswith('u"'):
        return text[text.index('"') + 1:-1]
    if text.startswith("'"):
        return ord(text[1:-1]) if len(text) == 3 else text[1:-1]
    integer = re.fullmatch(r"(-?\d+)[uUlL]*", text)
    if integer:
        return int(integer.group(1))
    return float(text.rstrip("fFlL"))


def rosidl_c_constants(prefix, package):
    """{(Name, CONSTANT): (value, C text)} from rosidl_generator_c's struct headers of a package.
    It writes integer, character and octet constants as `enum { pkg__msg__Name__X = v };`,
    floating point and boolean ones as `static const T pkg__msg__Name__X = v;`, strings as
    `static const char * const pkg__msg__Name__X = "v";` (msg__struct.h.em). Its
    `pkg__msg__Name__field__MAX_SIZE` / `__MAX_STRING_SIZE` enums of bounded fields are not
    constants of the message (a constant name has no "__")."""
    constants = {}
    pattern = re.compile(
        r"enum\s*\{\s*(\w+)\s*=\s*(.*?)\s*\};"
        r"|static\s+const\s+[^=;]*?\b(\w+)\s*=\s*(.*?);", re.S)
    for header in sorted((prefix / "include").rglob("msg/detail/*__struct.h")):
        for match in pattern.finditer(header.read_text()):
            symbol = match.group(1) or match.group(3)
            text = match.group(2) if match.group(1) else match.group(4)
            found = re.fullmatch(rf"{re.escape(package)}__msg__([A-Za-z0-9]+)__(\w+)", symbol)
            if found and "__" not in found.group(2):
                constants[(found.group(1), found.group(2))] = (c_value(text), text)
    return constants


def idlc_constants(h_lines, package, name):
    """{CONSTANT: (value, text)} from idlc's `#define pkg_msg_Name_Constants_X v` lines."""
    prefix = f"#define {package}_msg_{name}_Constants_"
    constants = {}
    for line in h_lines:
        if line.startswith(prefix):
            constant, _, text = line[len(prefix):].partition(" ")
            constants[constant] = (c_value(text), text)
    return constants


def constants_equal(rosidl, idlc):
    (rosidl_value, _), (idlc_value, idlc_text) = rosidl, idlc
    if isinstance(rosidl_value, bool) or isinstance(idlc_value, bool):
        return rosidl_value is idlc_value
    if isinstance(rosidl_value, float) or isinstance(idlc_value, float):
        # idlc prints floating point constants with %f (six decimals).
        return (f"{float(rosidl_value):f}" == idlc_text.strip()
                or float(rosidl_value) == float(idlc_value))
    return type(rosidl_value) is type(idlc_value) and rosidl_value == idlc_value


def short_diff(ours, derived, ours_name, derived_name, limit=30):
    lines = list(difflib.unified_diff(ours, derived, ours_name, derived_name, lineterm="", n=1))
    if len(lines) > limit:
        lines = lines[:limit] + [f"... ({len(lines) - limit} more diff lines)"]
    return "\n".join("      " + line for line in lines)


def compare(ours_root, ours_out, derived_out, walked, c_constants, quiet=False):
    """Step c for every type; returns the counts and the list of problems found."""
    say = (lambda message: None) if quiet else log
    problems = []
    ours_keys = {p.relative_to(ours_root).with_suffix("").as_posix()
                 for p in ours_root.rglob("*.idl")}
    ros_keys = set(walked)
    for key in sorted(ours_keys - ros_keys):
        problems.append(f"{key}: the project has IDL for it, but no ROS package built it")
    derived_only = []
    for key in sorted(ros_keys - ours_keys):
        if key.split("/")[0] in DERIVED_ONLY:
            derived_only.append(key)
        else:
            problems.append(f"{key}: ROS builds it (a .msg), but the project has no IDL for it")
    types = sorted(ours_keys & ros_keys)
    name_differences = idlc_differences = constant_count = constant_differences = 0
    for key in types:
        package, _, name = key.split("/")
        derived_name = walked[key]["dds_name"]
        ours, derived = ours_out.get(key), derived_out.get(key)
        if isinstance(derived, str):
            problems.append(f"{key}: the derived IDL does not compile: {derived}")
            idlc_differences += 1
            continue
        if isinstance(ours, str):
            problems.append(f"{key}: the project's IDL does not compile: {ours}")
            idlc_differences += 1
            name_differences += 1
            continue
        # The name the project's code registers (idlc's topic descriptor).
        registered = re.findall(r'\.m_typename = "([^"]+)"', "\n".join(ours[0]))
        if registered != [derived_name]:
            name_differences += 1
            problems.append(f"{key}: the project registers {registered}, rmw_cyclonedds_cpp "
                            f"uses {derived_name}")
        for index, suffix in enumerate((".c", ".h")):
            if ours[index] != derived[index]:
                idlc_differences += 1
                problems.append(f"{key}: idlc's {suffix} differs (project's IDL vs derived):\n" +
                                short_diff(ours[index], derived[index], f"project/{key}{suffix}",
                                           f"derived/{key}{suffix}"))
                break
        # Constants: rosidl's C headers against idlc's #defines of the project's IDL.
        rosidl = {const: value for (owner, const), value in c_constants[package].items()
                  if owner == name}
        defined = idlc_constants(ours[1], package, name)
        for const in sorted(set(rosidl) | set(defined)):
            constant_count += 1
            if const not in defined:
                constant_differences += 1
                problems.append(f"{key}: constant {const} = {rosidl[const][1]} in rosidl's C "
                                "header, not defined by the project's IDL")
            elif const not in rosidl:
                constant_differences += 1
                problems.append(f"{key}: constant {const} = {defined[const][1]} in the project's "
                                "IDL, not in rosidl's C header")
            elif not constants_equal(rosidl[const], defined[const]):
                constant_differences += 1
                problems.append(f"{key}: constant {const}: rosidl's C header says "
                                f"{rosidl[const][1]}, idlc's #define says {defined[const][1]}")
    # Every derived IDL compiles, the derived-only types too.
    for key in derived_only:
        if isinstance(derived_out.get(key), str):
            problems.append(f"{key}: the derived IDL does not compile: {derived_out[key]}")
    summary = (f"{len(types)} types, {name_differences} name differences, {idlc_differences} "
               f"idlc differences, {constant_count} constants, {constant_differences} differences")
    for problem in problems:
        say("  DIFFERENCE: " + problem)
    if derived_only:
        say(f"  ({len(derived_only)} ROS types derived only, the project has no IDL for them: "
            + ", ".join(derived_only) + ")")
    return summary, problems


# --- the self-test -----------------------------------------------------------------------------

MEMBER_LINE = re.compile(r"^(\s*)([A-Za-z_][\w:<>, ]*?)\s+([a-z_][a-z0-9_]*)(\[\d+\])?;")
CONSTANT_LINE = re.compile(r"^(\s*const\s+\w+\s+\w+\s*=\s*)(\d+)(;.*)$")


def struct_members(lines):
    """Indexes of the member lines of the @final struct in an IDL file's lines."""
    inside, members = False, []
    for index, line in enumerate(lines):
        if re.match(r"\s*@final\s+struct\s", line):
            inside = True
        elif inside and line.strip().startswith("};"):
            break
        elif inside and MEMBER_LINE.match(line):
            members.append(index)
    return members


def mutate_swap(lines):
    """Swaps two adjacent members, preferring two of the same type (only their names then tell
    them apart, as in Heartbeat's session_id and sequence_number)."""
    members = struct_members(lines)
    pairs = list(zip(members, members[1:]))
    same = [(a, b) for a, b in pairs
            if MEMBER_LINE.match(lines[a]).group(2) == MEMBER_LINE.match(lines[b]).group(2)]
    for a, b in same + pairs:
        lines[a], lines[b] = lines[b], lines[a]
        return (f"swapped `{lines[b].split('//')[0].strip()}` and "
                f"`{lines[a].split('//')[0].strip()}`")
    return None


def mutate_bound(lines):
    """Bounds an unbounded string member (string x -> string<8> x), else a sequence."""
    for pattern, replacement in ((r"^(\s*)string(\s+\w+;)", r"\1string<8>\2"),
                                 (r"^(\s*)sequence<([^,>]+)>(\s+\w+;)", r"\1sequence<\2, 8>\3")):
        for index in struct_members(lines):
            changed = re.sub(pattern, replacement, lines[index])
            if changed != lines[index]:
                before = lines[index].strip()
                lines[index] = changed
                return f"`{before}` -> `{changed.strip()}`"
    return None


def mutate_constant(lines):
    """Changes one constant's value by one."""
    for index, line in enumerate(lines):
        match = CONSTANT_LINE.match(line)
        if match:
            value = int(match.group(2))
            new = value + 1 if value < 100 else value - 1
            lines[index] = f"{match.group(1)}{new}{match.group(3)}"
            return f"`{line.strip()}` -> `{lines[index].strip()}`"
    return None


def self_test(work, ours_root, idlc, derived_out, walked, c_constants):
    """Each mutation of a copy of the project's IDL must make step c report a difference."""
    log("self-test: three mutations of a copy of the project's IDL, each must be reported")
    failures = 0
    mutations = (("fields swapped", mutate_swap), ("bound changed", mutate_bound),
                 ("constant changed", mutate_constant))
    for number, (title, mutate) in enumerate(mutations, 1):
        scratch = work / "selftest" / f"{number}" / "idl"
        shutil.copytree(ours_root, scratch)
        description = None
        for idl in sorted((scratch / PACKAGE / "msg").glob("*.idl")):
            lines = idl.read_text().splitlines()
            description = mutate(lines)
            if description:
                idl.write_text("\n".join(lines) + "\n")
                break
        if description is None:
            log(f"  {number}. {title}: FAILED: no autodrive_msgs IDL file to mutate")
            failures += 1
            continue
        where = idl.relative_to(scratch).as_posix()
        mutated_out = idlc_outputs(idlc, scratch, work / "selftest" / f"{number}" / "idlc")
        summary, problems = compare(scratch, mutated_out, derived_out, walked, c_constants,
                                    quiet=True)
        if problems:
            first = problems[0].splitlines()[0]
            log(f"  {number}. {title} in {where}: {description}: detected ({summary}; "
                f"first: {first.rstrip(':')})")
        else:
            log(f"  {number}. {title} in {where}: {description}: NOT DETECTED ({summary})")
            failures += 1
    log(f"self-test: {3 - failures} of 3 mutations detected")
    return failures == 0


# --- main ----------------------------------------------------------------------------------------

def main():
    parser = argparse.ArgumentParser(
        description="Checks that the project's DDS types (common/msgs/idl, compiled by idlc) are "
                    "those ROS 2's rmw_cyclonedds_cpp derives from ros2/autodrive_msgs and the "
                    "vendored upstream .msg files (tests/ros2/upstream), built with Debian's "
                    "colcon and rosidl. See tests/ros2/README.md.",
        epilog="Needs Debian's " + DEBIAN_PACKAGES + "; run it with /usr/bin/python3.")
    parser.add_argument("--source", type=Path, default=HERE.parent.parent,
                        help="the repository's root (default: %(default)s)")
    parser.add_argument("--idlc", default="idlc", help="Cyclone's idlc (default: idlc on PATH)")
    parser.add_argument("--work", help="work folder: created, or emptied if an earlier run made "
                        "it (default: a temporary folder, removed after a passing run)")
    parser.add_argument("--self-test", action="store_true",
                        help="after the check, mutate a copy of the project's IDL three times "
                             "and fail unless each mutation is reported")
    parser.add_argument("--reuse-build", action="store_true",
                        help="reuse the colcon workspaces an earlier run left in --work (no "
                             "colcon build; for working on the check itself)")
    parser.add_argument("--cc", default=os.environ.get("CC", "cc"),
                        help="C compiler for introspection_walk.c (default: $CC or cc)")
    args = parser.parse_args()
    if args.reuse_build and not args.work:
        parser.error("--reuse-build needs --work")
    args.source = args.source.resolve()
    ours_root = args.source / "common" / "msgs" / "idl"
    if not (args.source / "ros2" / PACKAGE).is_dir() or not ours_root.is_dir():
        parser.error(f"--source {args.source}: no ros2/{PACKAGE} or common/msgs/idl there")
    if shutil.which(args.idlc):
        args.idlc = shutil.which(args.idlc)

    started = time.monotonic()
    work = None
    try:
        check_prerequisites(args)
        work = prepare_work(args)
        log(f"work folder: {work}")
        env = base_environment(work)
        if args.reuse_build:
            deps, ws = work / "deps", work / "ws"
            prefixes = {name: deps / "install" / name for name in VENDORED}
            prefixes[PACKAGE] = package_prefix(ws / "install", PACKAGE)
            if prefixes[PACKAGE] is None or not all(p.is_dir() for p in prefixes.values()):
                raise CheckError(f"--reuse-build: no complete earlier build in {work}")
            env = sourced_environment(env, [deps / "install" / "setup.bash",
                                            ws / "install" / "setup.bash"])
            log("a. reusing the colcon workspaces of an earlier run (--reuse-build)")
        else:
            prefixes, env, deps_seconds, ws_seconds = build_workspaces(work, args.source, env)

        walked = walk_types(work, prefixes, env, args.cc)
        derived_root, _ = write_derived_idl(work, walked, prefixes)
        c_constants = {package: rosidl_c_constants(prefix, package)
                       for package, prefix in prefixes.items()}

        log(f"c. idlc ({args.idlc} -x final) on the project's IDL ({ours_root}) and the derived "
            "IDL; names, outputs, constants")
        ours_out = idlc_outputs(args.idlc, ours_root, work / "idlc" / "project")
        derived_out = idlc_outputs(args.idlc, derived_root, work / "idlc" / "derived")
        summary, problems = compare(ours_root, ours_out, derived_out, walked, c_constants)
        log(summary)
        passed = not problems
        if passed and args.self_test:
            passed = self_test(work, ours_root, args.idlc, derived_out, walked, c_constants)
        elif args.self_test:
            log("self-test: not run, the check itself failed")
        log(f"{'PASSED' if passed else 'FAILED'} in {time.monotonic() - started:.0f} s")
    except CheckError as error:
        log(f"ERROR: {error}")
        if work is not None:
            log(f"(work folder kept: {work})")
        return 2 if work is None else 1
    if args.work is None and passed:
        shutil.rmtree(work)
    elif not passed:
        log(f"(work folder kept: {work})")
    return 0 if passed else 1


if __name__ == "__main__":
    sys.exit(main())
