# Turn a text file into a C header holding it as a NUL-terminated char array (bytes,
# not a string literal: no length limit, no escaping). Run as
#   cmake -DINPUT=player.html -DOUTPUT=player_html.h -DNAME=rbc_player_html -P embed.cmake
file(READ "${INPUT}" hex HEX)
string(REGEX REPLACE "([0-9a-f][0-9a-f])" "0x\\1," bytes "${hex}")
# A line of the header per line of the input keeps it readable in an editor.
string(REPLACE "0x0a," "0x0a,\n" bytes "${bytes}")
file(WRITE "${OUTPUT}.tmp"
  "/* Generated from ${INPUT} by embed.cmake; do not edit. */\n"
  "static const char ${NAME}[] = {\n${bytes}0x00};\n")
file(RENAME "${OUTPUT}.tmp" "${OUTPUT}")
