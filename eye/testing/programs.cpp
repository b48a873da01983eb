#include "eye/testing/programs.h"

#include <chrono>

#include "common/process.h"

namespace autodrive::eye::testing {

std::string ProgramPath(const std::string& name) { return ExecutableDir() + "/" + name; }

ProgramOutput RunProgram(const std::vector<std::string>& argv) {
  std::vector<std::string> sh{"/bin/sh", "-c", "exec \"$@\" 2>&1", "sh"};
  sh.insert(sh.end(), argv.begin(), argv.end());
  ChildProcess p(sh, {});
  ProgramOutput out;
  while (auto line = p.ReadLine(std::chrono::minutes(5))) out.text += *line + "\n";
  out.code = p.Wait(std::chrono::minutes(1)).value_or(-1);
  return out;
}

}  // namespace autodrive::eye::testing
