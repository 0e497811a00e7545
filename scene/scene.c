/* being written */
typedef int rr_unused_tu;
