/*
 * Test-only stand-in for Windows' bcryptprimitives.dll under wine 8, which lacks ProcessPrng
 * (present on Windows 10/11). Rust's std on Windows imports ProcessPrng (for HashMap seeds);
 * without it an FMU DLL cannot load under wine. This shim fills the buffer from
 * RtlGenRandom (advapi32's SystemFunction036). It is never shipped in an FMU.
 */
#include <windows.h>

BOOLEAN NTAPI SystemFunction036(PVOID buffer, ULONG length);

__declspec(dllexport) BOOL WINAPI ProcessPrng(PBYTE data, SIZE_T length) {
    while (length > 0) {
        ULONG chunk = length > 0x10000000 ? 0x10000000 : (ULONG)length;
        if (!SystemFunction036(data, chunk)) return FALSE;
        data += chunk;
        length -= chunk;
    }
    return TRUE;
}
