//! Run-time choice of instruction set for the hot loops, in one place.
//!
//! [`x86_dispatch!`] defines a function that runs a body compiled for AVX-512F where the CPU
//! has it, for AVX where it has that, and the portable build otherwise. The bodies are plain
//! Rust (`#[inline(always)]` helpers, often with a tile width as a const parameter): Rust never
//! fuses a multiply and an add, so every build gives the same bits as long as each element
//! sees its operations in the same order; the tests of each user compare the builds.

/// `fn NAME(args) [-> RET]` running `avx512: EXPR` compiled for AVX-512F, `avx: EXPR` for AVX,
/// or `portable: EXPR`, chosen at run time (`is_x86_feature_detected!`, cached by std). The
/// expressions see the arguments by name.
macro_rules! x86_dispatch {
    (
        $(#[$doc:meta])*
        $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)? {
            avx512: $avx512:expr,
            avx: $avx:expr,
            portable: $portable:expr $(,)?
        }
    ) => {
        $(#[$doc])*
        $vis fn $name($($arg: $ty),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            {
                /// The body compiled for AVX-512F.
                ///
                /// # Safety
                /// The CPU must have AVX-512F.
                #[target_feature(enable = "avx512f")]
                unsafe fn avx512($($arg: $ty),*) $(-> $ret)? {
                    $avx512
                }
                /// The body compiled for AVX.
                ///
                /// # Safety
                /// The CPU must have AVX.
                #[target_feature(enable = "avx")]
                unsafe fn avx($($arg: $ty),*) $(-> $ret)? {
                    $avx
                }
                if std::arch::is_x86_feature_detected!("avx512f") {
                    // SAFETY: this CPU has AVX-512F (checked just above).
                    return unsafe { avx512($($arg),*) };
                }
                if std::arch::is_x86_feature_detected!("avx") {
                    // SAFETY: this CPU has AVX (checked just above).
                    return unsafe { avx($($arg),*) };
                }
            }
            $portable
        }
    };
}
pub(crate) use x86_dispatch;
