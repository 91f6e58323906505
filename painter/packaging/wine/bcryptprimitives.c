/* A stand-in for Windows' bcryptprimitives.dll, for tests under Wine 8 only
 * (never shipped: Windows 10 and later have the real one, and Wine 9 and
 * later build it in). Rust's standard library takes its random bytes from
 * ProcessPrng, which Wine 8 lacks, so without this no Rust program starts
 * there. RtlGenRandom (advapi32's SystemFunction036) gives the same bytes
 * from the same system source. run.sh builds it into the Wine prefix. */
#include <windows.h>

BOOLEAN WINAPI SystemFunction036(PVOID buffer, ULONG length);

__declspec(dllexport) BOOL WINAPI ProcessPrng(PBYTE data, SIZE_T length) {
    while (length > 0) {
        ULONG n = length > 0x40000000 ? 0x40000000 : (ULONG)length;
        if (!SystemFunction036(data, n)) return FALSE;
        data += n;
        length -= n;
    }
    return TRUE;
}
