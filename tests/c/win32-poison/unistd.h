/* Windows compile check (tests/c Makefile, target windows): mingw ships
 * <unistd.h>, MSVC does not. A Windows-selected file that includes it uses a
 * POSIX call: reach the OS through csrc/port/runtime/co_rt_os.h instead. */
#error "<unistd.h> in a Windows-selected source: MSVC has no such header (use co_rt_os.h)"
