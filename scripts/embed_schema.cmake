# Turns configs/schema.json into a C++ source holding it as a string.
file(READ ${IN} content)
file(WRITE ${OUT} "// Generated from configs/schema.json; do not edit.\n")
file(APPEND ${OUT} "namespace rtsim { extern const char* const kConfigSchemaJson;\n")
file(APPEND ${OUT} "const char* const kConfigSchemaJson = R\"rtsim_schema(${content})rtsim_schema\"; }\n")
