// RbcException.cs -- a failing rbcloth call as an exception: the rbc_result code, its
// name (rbc_result_string) and rbc_last_error()'s message, which names the object,
// the index and what was wrong. The message is read on the calling thread right
// after the call, since rbc_last_error is per thread.
using System;

namespace RbCloth.Native
{
    public sealed class RbcException : Exception
    {
        /// <summary>The rbc_result code (negative), e.g. RbcNative.RBC_ERR_BAD_MESH.</summary>
        public int Result { get; private set; }
        /// <summary>The code's name, e.g. "RBC_ERR_BAD_MESH".</summary>
        public string ResultName { get; private set; }
        /// <summary>rbc_last_error() at the failure (or the binding's own reason).</summary>
        public string LibraryMessage { get; private set; }

        public RbcException(int result, string message, Exception inner = null)
            : base(RbcNative.ResultName(result) + ": " + message, inner)
        {
            Result = result;
            ResultName = RbcNative.ResultName(result);
            LibraryMessage = message;
        }

        /// <summary>Throw unless `result` is RBC_OK. Call it directly after the native
        /// call, on the same thread, so rbc_last_error is that call's.</summary>
        public static void Check(int result)
        {
            if (result != RbcNative.RBC_OK)
                throw new RbcException(result, RbcNative.LastError());
        }
    }
}
