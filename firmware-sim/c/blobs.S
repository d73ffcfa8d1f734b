/* The model blob and the replay image, embedded in FLASH (.rodata) at build time; the Makefile
 * passes their paths as BLOB_PATH and IMAGE_PATH. The blob is 16-byte aligned (its parameters
 * are 16-byte aligned relative to its start), the image 4-byte aligned (its RGB records are). */
    .section .rodata.depthor_blobs, "a"
    .balign 16
    .global depthor_model_blob
depthor_model_blob:
    .incbin BLOB_PATH
    .global depthor_model_blob_end
depthor_model_blob_end:
    .balign 4
    .global replay_image_bytes
replay_image_bytes:
    .incbin IMAGE_PATH
    .global replay_image_bytes_end
replay_image_bytes_end:
    .section .note.GNU-stack, "", %progbits
