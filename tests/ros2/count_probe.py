"""Builds tests/ros2/count_probe.c, the independent subscriber of record_city.py and the netns
tests, with C types idlc makes from the IDL *derived from Debian's rosidl* (ros2_interfaces_test's
work folder, the ros2_workspace fixture) and a table `probe_types` of their descriptors."""

import pathlib
import subprocess


def build(source, ros2_work, idlc, cc, work):
    """Returns the probe's path, built in `work`. Raises RuntimeError when the derived IDL is
    missing (ros2_interfaces_test has not run)."""
    derived = pathlib.Path(ros2_work) / "derived_idl"
    idls = sorted(derived.rglob("*.idl"))
    if len(idls) < 40:
        raise RuntimeError(f"{derived} has {len(idls)} IDL files: run ros2_interfaces_test "
                           "first (its fixture)")
    work = pathlib.Path(work)
    gen = work / "gen"
    gen.mkdir(parents=True)
    names = []
    for idl in idls:
        subprocess.run([idlc, "-x", "final", "-I", str(derived), "-b", str(derived), "-o",
                        str(gen), str(idl)], check=True)
        relative = idl.relative_to(derived).with_suffix("")  # pkg/msg/Type
        names.append((relative, "_".join(relative.parts[:-1]) + f"_dds__{relative.name}__desc"))
    table = work / "probe_types.c"
    table.write_text("".join(f'#include "{r}.h"\n' for r, _ in names) +
                     "const dds_topic_descriptor_t* const probe_types[] = {\n" +
                     "".join(f"  &{d},\n" for _, d in names) + "  NULL};\n")
    probe = work / "count_probe"
    subprocess.run([cc, "-std=gnu11", "-O2", "-o", str(probe),
                    str(pathlib.Path(source) / "tests" / "ros2" / "count_probe.c"), str(table),
                    *[str(p) for p in sorted(gen.rglob("*.c"))], "-I", str(gen), "-lddsc"],
                   check=True)
    return probe
