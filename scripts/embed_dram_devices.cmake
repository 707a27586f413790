# Turns configs/dram/*.json (DRAM device presets) into a C++ source that registers each one by
# its file name in the DRAM device registry (models/dram_device.h), so `rtsim list` shows them
# and dram.device selects them without the source tree at hand.
file(WRITE ${OUT} "// Generated from configs/dram/*.json; do not edit.\n#include \"models/dram_device.h\"\nnamespace rtsim {\n")
set(i 0)
foreach(f ${IN})
  file(READ ${f} content)
  get_filename_component(name ${f} NAME_WE)
  string(JSON description GET "${content}" description)
  string(REPLACE "\"" "\\\"" description "${description}")
  file(APPEND ${OUT} "RTSIM_REGISTER(DramDeviceEntry, {\"${name}\", \"${description}\", {}, R\"rtsim_dram(${content})rtsim_dram\"})\n")
  math(EXPR i "${i} + 1")
endforeach()
file(APPEND ${OUT} "}  // namespace rtsim\n")
