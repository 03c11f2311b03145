//! Run-time choice of instruction set for the hot loops, in one place.
//!
//! [`x86_dispatch!`] defines a function that runs a body compiled for AVX-512F where the CPU
//! has it, for AVX where it has that, and the portable build otherwise. The bodies are plain
//! Rust (`#[inline(always)]` helpers, often with a tile width as a const parameter): Rust never
//! fuses a multiply and an add, so every build gives the same bits as long as each element
//! sees its operations in the same order; the tests of each user compare the builds (the
//! AVX-512F and AVX ones are named, so a test can call each that the CPU runs).

/// `fn NAME(args) [-> RET]` running `avx512 NAME512: EXPR` compiled for AVX-512F, `avx
/// NAMEAVX: EXPR` for AVX, or `portable: EXPR`, chosen at run time (`is_x86_feature_detected!`,
/// cached by std). `NAME512` and `NAMEAVX` are the two compiled copies (unsafe: the CPU must
/// have the feature). The expressions see the arguments by name.
macro_rules! x86_dispatch {
    (
        $(#[$doc:meta])*
        $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)? {
            avx512 $avx512_name:ident: $avx512:expr,
            avx $avx_name:ident: $avx:expr,
            portable: $portable:expr $(,)?
        }
    ) => {
        $(#[$doc])*
        $vis fn $name($($arg: $ty),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            {
                if std::arch::is_x86_feature_detected!("avx512f") {
                    // SAFETY: this CPU has AVX-512F (checked just above).
                    return unsafe { $avx512_name($($arg),*) };
                }
                if std::arch::is_x86_feature_detected!("avx") {
                    // SAFETY: this CPU has AVX (checked just above).
                    return unsafe { $avx_name($($arg),*) };
                }
            }
            $portable
        }

        #[doc = concat!("[`", stringify!($name), "`] compiled for AVX-512F.")]
        ///
        /// # Safety
        /// The CPU must have AVX-512F.
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx512f")]
        unsafe fn $avx512_name($($arg: $ty),*) $(-> $ret)? {
            $avx512
        }

        #[doc = concat!("[`", stringify!($name), "`] compiled for AVX.")]
        ///
        /// # Safety
        /// The CPU must have AVX.
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx")]
        unsafe fn $avx_name($($arg: $ty),*) $(-> $ret)? {
            $avx
        }
    };
}
pub(crate) use x86_dispatch;

/// The compiled builds of [`x86_dispatch!`] this CPU runs besides the portable one (`"avx"`,
/// `"avx512"`), for the tests that compare each with it.
#[cfg(test)]
pub(crate) fn builds_here() -> Vec<&'static str> {
    let mut v = Vec::new();
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx") {
            v.push("avx");
        }
        if std::arch::is_x86_feature_detected!("avx512f") {
            v.push("avx512");
        }
    }
    v
}
