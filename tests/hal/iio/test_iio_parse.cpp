// The IIO parsers: scan element type strings, sysfs numbers, mount matrices, scan_elements discovery,
// scan layout (alignment, padding) and value unpacking (endianness, shift, mask, sign extension),
// including malformed input.
#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

#include "iio/fake_iio_tree.hpp"
#include "iio/iio_parse.hpp"

using namespace locus::hal::iio;
using locus::iio_fake::FakeIioTree;

namespace {

/// The message of the IioError `f` throws ("" if it does not throw).
template <typename F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const IioError& e) {
    return e.what();
  }
  return "";
}

ScanChannel chan(std::string name, std::int64_t index, const std::string& type, bool enabled = true) {
  ScanChannel c;
  c.name = std::move(name);
  c.index = index;
  c.type = parse_scan_type(type);
  c.enabled = enabled;
  return c;
}

}  // namespace

TEST(IioScanType, ParsesKernelForms) {
  ScanType t = parse_scan_type("le:s16/16>>0");
  EXPECT_FALSE(t.big_endian);
  EXPECT_TRUE(t.is_signed);
  EXPECT_EQ(t.bits, 16u);
  EXPECT_EQ(t.storage_bits, 16u);
  EXPECT_EQ(t.repeat, 1u);
  EXPECT_EQ(t.shift, 0u);
  EXPECT_EQ(t.storage_bytes(), 2u);

  t = parse_scan_type("be:u12/16>>4\n");
  EXPECT_TRUE(t.big_endian);
  EXPECT_FALSE(t.is_signed);
  EXPECT_EQ(t.bits, 12u);
  EXPECT_EQ(t.storage_bits, 16u);
  EXPECT_EQ(t.shift, 4u);

  t = parse_scan_type(std::string("le:s64/64>>0\n\0", 14));
  EXPECT_EQ(t.bits, 64u);
  EXPECT_EQ(t.storage_bytes(), 8u);

  t = parse_scan_type("le:s16/16X3>>0");
  EXPECT_EQ(t.repeat, 3u);
  EXPECT_EQ(t.element_bytes(), 2u);
  EXPECT_EQ(t.storage_bytes(), 6u);

  t = parse_scan_type("le:u8/8");  // shift omitted
  EXPECT_EQ(t.shift, 0u);
  EXPECT_EQ(t.storage_bits, 8u);
}

TEST(IioScanType, FormatRoundTrips) {
  for (const char* s : {"le:s16/16>>0", "be:u12/16>>4", "le:s64/64>>0", "le:s16/16X3>>0", "be:s24/32>>8"}) {
    EXPECT_EQ(format_scan_type(parse_scan_type(s)), s);
  }
}

TEST(IioScanType, RejectsMalformed) {
  EXPECT_NE(error_of([] { parse_scan_type("le:s16 16>>0"); }).find("missing '/'"), std::string::npos);
  EXPECT_NE(error_of([] { parse_scan_type("le:s20/16>>0"); }).find("bits 20 must be 1..16"), std::string::npos);
  EXPECT_NE(error_of([] { parse_scan_type("me:s16/16>>0"); }).find("unknown endianness 'me'"), std::string::npos);
  EXPECT_NE(error_of([] { parse_scan_type("le:x16/16>>0"); }).find("sign must be"), std::string::npos);
  EXPECT_NE(error_of([] { parse_scan_type("le:s16/12>>0"); }).find("storagebits 12"), std::string::npos);
  EXPECT_NE(error_of([] { parse_scan_type("le:s12/16>>6"); }).find("exceeds storagebits"), std::string::npos);
  EXPECT_NE(error_of([] { parse_scan_type("le:s16/16>>"); }).find("bad <shift>"), std::string::npos);
  EXPECT_NE(error_of([] { parse_scan_type("le:s16/16>0"); }).find("unexpected '>0'"), std::string::npos);
  EXPECT_NE(error_of([] { parse_scan_type("le:s16/16>>0 junk"); }).find("after the shift"), std::string::npos);
  EXPECT_NE(error_of([] { parse_scan_type("le:s16/16X0>>0"); }).find("repeat 0"), std::string::npos);
  EXPECT_NE(error_of([] { parse_scan_type("le:s0/16>>0"); }).find("bits 0"), std::string::npos);
  EXPECT_NE(error_of([] { parse_scan_type("le:s/16>>0"); }).find("bad <bits>"), std::string::npos);
  EXPECT_NE(error_of([] { parse_scan_type(""); }).find("empty"), std::string::npos);
  EXPECT_NE(error_of([] { parse_scan_type("le:s99999999999/16>>0"); }).find("bad <bits>"), std::string::npos);
  // Every message quotes the text and the grammar.
  const std::string e = error_of([] { parse_scan_type("le:s16x16"); });
  EXPECT_NE(e.find("'le:s16x16'"), std::string::npos) << e;
  EXPECT_NE(e.find("[be|le]:[s|u]<bits>/<storagebits>"), std::string::npos) << e;
}

TEST(IioSysfsValues, TolerantOfNewlineAndNul) {
  EXPECT_EQ(trim_sysfs("0.000598550\n"), "0.000598550");
  EXPECT_EQ(trim_sysfs(std::string_view("lsm6dsl\n\0\0", 10)), "lsm6dsl");
  EXPECT_DOUBLE_EQ(parse_sysfs_double("0.000598550\n", "f"), 0.000598550);
  EXPECT_DOUBLE_EQ(parse_sysfs_double(std::string_view("1.5\0", 4), "f"), 1.5);
  EXPECT_DOUBLE_EQ(parse_sysfs_double("-2", "f"), -2.0);
  EXPECT_DOUBLE_EQ(parse_sysfs_double("+1e-3", "f"), 1e-3);
  EXPECT_EQ(parse_sysfs_int("-32768\n", "f"), -32768);
  EXPECT_EQ(parse_sysfs_int("1700000000000000000", "f"), 1700000000000000000LL);
}

TEST(IioSysfsValues, RejectsGarbage) {
  EXPECT_NE(error_of([] { parse_sysfs_double("", "in_accel_scale"); }).find("in_accel_scale: '' is empty"), std::string::npos);
  EXPECT_NE(error_of([] { parse_sysfs_double("abc", "s"); }).find("not a number"), std::string::npos);
  EXPECT_NE(error_of([] { parse_sysfs_double("0.5x", "s"); }).find("trailing characters 'x'"), std::string::npos);
  EXPECT_NE(error_of([] { parse_sysfs_double("1e999", "s"); }).find("out of range"), std::string::npos);
  EXPECT_NE(error_of([] { parse_sysfs_double("nan", "s"); }).find("not finite"), std::string::npos);
  EXPECT_NE(error_of([] { parse_sysfs_double("0.1 0.2", "s"); }).find("trailing"), std::string::npos);
  EXPECT_NE(error_of([] { parse_sysfs_int("1.5", "i"); }).find("trailing characters '.5'"), std::string::npos);
  EXPECT_NE(error_of([] { parse_sysfs_int("99999999999999999999", "i"); }).find("out of range"), std::string::npos);
  EXPECT_NE(error_of([] { parse_sysfs_int("x", "i"); }).find("not an integer"), std::string::npos);
}

TEST(IioMountMatrix, ParsesAndRejects) {
  const Matrix3 m = parse_mount_matrix("0, 1, 0; -1, 0, 0; 0, 0, 1\n", "mm");
  EXPECT_EQ(m[0][1], 1.0);
  EXPECT_EQ(m[1][0], -1.0);
  EXPECT_EQ(m[2][2], 1.0);
  EXPECT_EQ(m[0][0], 0.0);
  EXPECT_NE(error_of([] { parse_mount_matrix("1, 0, 0; 0, 1, 0", "mm"); }).find("has 2 rows"), std::string::npos);
  EXPECT_NE(error_of([] { parse_mount_matrix("1, 0; 0, 1, 0; 0, 0, 1", "mm"); }).find("row 1 has 2 values"),
            std::string::npos);
  EXPECT_NE(error_of([] { parse_mount_matrix("1, 0, 0, 0; 0, 1, 0; 0, 0, 1", "mm"); }).find("more than 3 values"),
            std::string::npos);
  EXPECT_NE(error_of([] { parse_mount_matrix("1, 0, 0; 0, a, 0; 0, 0, 1", "mm"); }).find("not a number"), std::string::npos);
}

TEST(IioLayout, SixS16PlusTimestampIs24Bytes) {
  std::vector<ScanChannel> ch{chan("in_accel_x", 0, "le:s16/16>>0"),   chan("in_accel_y", 1, "le:s16/16>>0"),
                              chan("in_accel_z", 2, "le:s16/16>>0"),   chan("in_anglvel_x", 3, "le:s16/16>>0"),
                              chan("in_anglvel_y", 4, "le:s16/16>>0"), chan("in_anglvel_z", 5, "le:s16/16>>0"),
                              chan("in_timestamp", 6, "le:s64/64>>0")};
  const ScanLayout l = compute_layout(ch);
  ASSERT_EQ(l.slots.size(), 7u);
  EXPECT_EQ(l.scan_bytes, 24u);
  for (std::size_t i = 0; i < 6; ++i) EXPECT_EQ(l.slots[i].offset, 2 * i);
  EXPECT_EQ(l.find("in_timestamp")->offset, 16u);
  EXPECT_EQ(l.find("in_magn_x"), nullptr);
}

TEST(IioLayout, AlignmentPaddingAndOrder) {
  // Index order, not listing order; disabled channels take no room.
  std::vector<ScanChannel> ch{chan("in_timestamp", 9, "le:s64/64>>0"), chan("in_b", 2, "le:s32/32>>0"),
                              chan("in_a", 1, "le:u8/8>>0"), chan("in_off", 3, "le:s16/16>>0", false)};
  ScanLayout l = compute_layout(ch);
  ASSERT_EQ(l.slots.size(), 3u);
  EXPECT_EQ(l.slots[0].name, "in_a");
  EXPECT_EQ(l.slots[0].offset, 0u);
  EXPECT_EQ(l.slots[1].offset, 4u);   // s32 aligned to 4
  EXPECT_EQ(l.slots[2].offset, 8u);   // s64 aligned to 8
  EXPECT_EQ(l.scan_bytes, 16u);
  // Total size padded to the largest storage: 3 x s16 + s32 = 6 -> 8 -> 12, padded to 12 (multiple of 4).
  l = compute_layout({chan("in_x", 0, "le:s16/16>>0"), chan("in_y", 1, "le:s16/16>>0"), chan("in_z", 2, "le:s16/16>>0"),
                      chan("in_w", 3, "le:s32/32>>0")});
  EXPECT_EQ(l.slots[3].offset, 8u);
  EXPECT_EQ(l.scan_bytes, 12u);
  // 3 x s16 alone: 6 bytes; with a u8 after them: 7 -> padded to 8.
  l = compute_layout({chan("in_x", 0, "le:s16/16>>0"), chan("in_y", 1, "le:s16/16>>0"), chan("in_z", 2, "le:s16/16>>0"),
                      chan("in_q", 3, "le:u8/8>>0")});
  EXPECT_EQ(l.scan_bytes, 8u);
  // A repeated channel occupies storage * repeat.
  l = compute_layout({chan("in_q", 0, "le:u8/8>>0"), chan("in_v", 1, "le:s16/16X2>>0")});
  EXPECT_EQ(l.slots[1].offset, 4u);
  EXPECT_EQ(l.scan_bytes, 8u);
}

TEST(IioLayout, RejectsNothingEnabledAndDuplicateIndex) {
  EXPECT_NE(error_of([] { compute_layout({chan("in_a", 0, "le:s16/16>>0", false)}); }).find("no scan element is enabled"),
            std::string::npos);
  EXPECT_NE(error_of([] { compute_layout({chan("in_a", 1, "le:s16/16>>0"), chan("in_b", 1, "le:s16/16>>0")}); })
                .find("share scan index 1"),
            std::string::npos);
}

TEST(IioUnpack, EndiannessShiftMaskAndSign) {
  std::uint8_t scan[16] = {};
  // le:s16: -2 = 0xfffe
  scan[0] = 0xfe;
  scan[1] = 0xff;
  EXPECT_EQ(unpack_value(scan, 0, parse_scan_type("le:s16/16>>0")), -2);
  EXPECT_EQ(unpack_value(scan, 0, parse_scan_type("le:u16/16>>0")), 0xfffe);
  // be:u12/16>>4: bytes 0xAB 0xCD -> 0xABCD >> 4 = 0xABC
  scan[2] = 0xab;
  scan[3] = 0xcd;
  EXPECT_EQ(unpack_value(scan, 2, parse_scan_type("be:u12/16>>4")), 0xabc);
  // be:s12/16>>4: 0xABC has the sign bit set -> 0xABC - 0x1000
  EXPECT_EQ(unpack_value(scan, 2, parse_scan_type("be:s12/16>>4")), 0xabc - 0x1000);
  // le: same bytes read as 0xCDAB, shifted: 0xCDA; masked 12 bits.
  EXPECT_EQ(unpack_value(scan, 2, parse_scan_type("le:u12/16>>4")), 0xcda);
  // Mask drops bits above `bits` even unshifted: 0xCDAB & 0x3ff.
  EXPECT_EQ(unpack_value(scan, 2, parse_scan_type("le:u10/16>>0")), 0xcdab & 0x3ff);
  // s64 little endian
  const std::int64_t ts = -1234567890123456789LL;
  for (int i = 0; i < 8; ++i) scan[8 + i] = static_cast<std::uint8_t>(static_cast<std::uint64_t>(ts) >> (8 * i));
  EXPECT_EQ(unpack_value(scan, 8, parse_scan_type("le:s64/64>>0")), ts);
  // 24-bit sample in 32-bit big-endian storage, shifted by 8.
  std::uint8_t b[4] = {0x80, 0x00, 0x01, 0x00};
  EXPECT_EQ(unpack_value(b, 0, parse_scan_type("be:s24/32>>8")), -(1 << 23) + 1);
}

TEST(IioUnpack, PackRoundTripsAndRepeat) {
  std::uint8_t scan[32] = {};
  const char* types[] = {"le:s16/16>>0", "be:s16/16>>0", "be:s12/16>>4", "le:u12/16>>4", "le:s64/64>>0", "be:s24/32>>8"};
  const std::int64_t values[] = {-32768, -1, 0, 1, 1000, 2047, -2048};
  for (const char* ts : types) {
    const ScanType t = parse_scan_type(ts);
    for (std::int64_t v : values) {
      if (!t.is_signed && v < 0) continue;
      if (t.bits < 64 && (v >= (std::int64_t{1} << (t.bits - (t.is_signed ? 1 : 0))) ||
                          v < -(std::int64_t{1} << (t.bits - 1)))) {
        continue;
      }
      pack_value(scan, 8, t, v);
      EXPECT_EQ(unpack_value(scan, 8, t), v) << ts << " " << v;
    }
  }
  const ScanType rep = parse_scan_type("le:s16/16X3>>0");
  pack_value(scan, 0, rep, -5, 0);
  pack_value(scan, 0, rep, 6, 1);
  pack_value(scan, 0, rep, -7, 2);
  EXPECT_EQ(unpack_value(scan, 0, rep, 0), -5);
  EXPECT_EQ(unpack_value(scan, 0, rep, 1), 6);
  EXPECT_EQ(unpack_value(scan, 0, rep, 2), -7);
  EXPECT_EQ(scan[2], 6);  // element 1 at byte 2
}

TEST(IioDiscover, ReadsScanElementsSortedByIndex) {
  FakeIioTree tree;
  const std::string d = tree.path("scan_elements");
  tree.write("scan_elements/in_b_en", "1\n");
  tree.write("scan_elements/in_b_index", "1\n");
  tree.write("scan_elements/in_b_type", "be:u12/16>>4\n");
  tree.write("scan_elements/in_a_en", "0");
  tree.write("scan_elements/in_a_index", "0");
  tree.write("scan_elements/in_a_type", std::string("le:s16/16>>0\n\0", 14));
  const std::vector<ScanChannel> ch = discover_scan_elements(d);
  ASSERT_EQ(ch.size(), 2u);
  EXPECT_EQ(ch[0].name, "in_a");
  EXPECT_FALSE(ch[0].enabled);
  EXPECT_EQ(ch[1].name, "in_b");
  EXPECT_TRUE(ch[1].enabled);
  EXPECT_EQ(ch[1].type, parse_scan_type("be:u12/16>>4"));
  EXPECT_TRUE(discover_scan_elements(tree.path("absent")).empty());
}

TEST(IioDiscover, MalformedFilesNameTheFile) {
  FakeIioTree tree;
  const std::string d = tree.path("scan_elements");
  tree.write("scan_elements/in_a_en", "1");
  tree.write("scan_elements/in_a_index", "0");
  std::string e = error_of([&] { discover_scan_elements(d); });
  EXPECT_NE(e.find(d + "/in_a_type: missing"), std::string::npos) << e;
  tree.write("scan_elements/in_a_type", "le:s16/16>>x");
  e = error_of([&] { discover_scan_elements(d); });
  EXPECT_NE(e.find(d + "/in_a_type: scan element type"), std::string::npos) << e;
  tree.write("scan_elements/in_a_type", "le:s16/16>>0");
  tree.write("scan_elements/in_a_en", "2");
  e = error_of([&] { discover_scan_elements(d); });
  EXPECT_NE(e.find("in_a_en: '2' (expected 0 or 1)"), std::string::npos) << e;
  tree.write("scan_elements/in_a_en", "1");
  tree.write("scan_elements/in_a_index", "zero");
  e = error_of([&] { discover_scan_elements(d); });
  EXPECT_NE(e.find("in_a_index: 'zero' is not an integer"), std::string::npos) << e;
  tree.write("scan_elements/in_a_index", "3");
  tree.write("scan_elements/in_b_en", "1");
  tree.write("scan_elements/in_b_index", "3");
  tree.write("scan_elements/in_b_type", "le:s16/16>>0");
  e = error_of([&] { discover_scan_elements(d); });
  EXPECT_NE(e.find("share scan index 3"), std::string::npos) << e;
}

TEST(IioSysfsFiles, ReadWriteAndMissing) {
  FakeIioTree tree;
  tree.write("v", "42\n");
  EXPECT_EQ(read_sysfs(tree.path("v")), "42");
  EXPECT_EQ(read_sysfs_int(tree.path("v")), 42);
  write_sysfs(tree.path("v"), "7");
  EXPECT_EQ(tree.read("v"), "7\n");
  std::string out = "untouched";
  EXPECT_FALSE(read_sysfs_optional(tree.path("nope"), out));
  EXPECT_EQ(out, "untouched");
  const std::string e = error_of([&] { read_sysfs(tree.path("nope")); });
  EXPECT_NE(e.find("cannot read " + tree.path("nope")), std::string::npos) << e;
  const std::string w = error_of([&] { write_sysfs(tree.path("no/dir/file"), "1"); });
  EXPECT_NE(w.find("cannot write '1' to " + tree.path("no/dir/file")), std::string::npos) << w;
}
