# Writes the shared library's version script: every lu_ name that the public
# headers (HEADERS) declare with an argument list is exported, nothing else.
# Names of static inline functions land in the list too; the linker ignores
# names the library does not define.
set(names "")
foreach(h ${HEADERS})
  file(READ ${h} text)
  string(REGEX MATCHALL "lu_[a-z0-9_]+[ \t]*\\(" found "${text}")
  foreach(f ${found})
    string(REGEX REPLACE "[ \t]*\\($" "" f "${f}")
    list(APPEND names ${f})
  endforeach()
endforeach()
list(REMOVE_DUPLICATES names)
list(SORT names)
set(map "{\n  global:\n")
foreach(n ${names})
  string(APPEND map "    ${n};\n")
endforeach()
string(APPEND map "  local:\n    *;\n};\n")
file(WRITE ${OUT}.tmp "${map}")
file(COPY_FILE ${OUT}.tmp ${OUT} ONLY_IF_DIFFERENT)
file(REMOVE ${OUT}.tmp)
