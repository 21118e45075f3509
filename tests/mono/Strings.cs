// Strings.cs -- a C# host (Mono) reading the library's borrowed strings the way the
// header says: declared as IntPtr and copied with Marshal.PtrToStringAnsi, never as a
// `string` return (which would make the marshaller free the library's own memory).
// It checks the ABI major, the version string, a result code's name and the message
// of a refused call, calling each one many times (a freed pointer would abort on the
// first or a later call). Exit status 0 when everything holds.
using System;
using System.Runtime.InteropServices;

static class Strings {
    [DllImport("rbcloth")] static extern uint rbc_abi_version();
    [DllImport("rbcloth")] static extern IntPtr rbc_version_string();
    [DllImport("rbcloth")] static extern IntPtr rbc_result_string(int result);
    [DllImport("rbcloth")] static extern IntPtr rbc_last_error();
    [DllImport("rbcloth")] static extern int rbc_world_step(uint world, float dt);

    static int Fail(string what) {
        Console.Error.WriteLine("mono_strings: " + what);
        return 1;
    }

    static int Main() {
        uint v = rbc_abi_version();
        if ((v >> 16) != 1) return Fail("ABI major " + (v >> 16));
        string version = null, name = null, message = null;
        for (int k = 0; k < 1000; ++k) {
            version = Marshal.PtrToStringAnsi(rbc_version_string());
            int rc = rbc_world_step(0, 0.01f); // id 0 is no world: RBC_ERR_STALE_HANDLE
            name = Marshal.PtrToStringAnsi(rbc_result_string(rc));
            message = Marshal.PtrToStringAnsi(rbc_last_error());
        }
        if (string.IsNullOrEmpty(version)) return Fail("empty version string");
        if (name != "RBC_ERR_STALE_HANDLE") return Fail("result name " + name);
        if (message == null || !message.Contains("rbc_world_step"))
            return Fail("last error \"" + message + "\" does not name the call");
        Console.WriteLine("mono_strings: ABI " + (v >> 16) + "." + (v & 0xFFFF) + ", version " +
                          version + ", " + name + ": " + message);
        return 0;
    }
}
