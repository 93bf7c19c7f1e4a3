/* ros_probe: an independent DDS participant that behaves like a ROS 2 node on rmw_cyclonedds,
 * written in plain C from the ROS 2 message definitions only (no refgrasp header, no IDL, no
 * idlc output). Like rmw_cyclonedds it registers its types by NAME with a custom sertype that
 * carries no XTypes type information, accepts only XCDR1, and (de)serialises the CDR by hand,
 * so it matches refgrasp's endpoints only if the topic and type names are exactly ROS's, and it
 * decodes their samples only if the byte layout is exactly ROS's.
 *
 *   ros_probe [--domain N] list [--wait S]
 *       every remote endpoint as "pub|sub <dds topic> <dds type>" (the DCPSPublication and
 *       DCPSSubscription built-in topics, as `ros2 topic list -t` sees them)
 *   ros_probe [--domain N] echo TOPIC TYPE [--count K] [--timeout S]
 *       subscribes (best effort, keep last 10) and prints each sample as one JSON line,
 *       {"encapsulation":..., "ok":..., "msg":{...}}; "ok" is false when the bytes do not decode
 *       exactly (truncated, or bytes left over)
 *   ros_probe [--domain N] pub-image NS PGM ENCODING [--frame F] [--f PX] [--count K] [--rate HZ]
 *             [--stamp0 S]
 *       publishes NS/image_raw (sensor_msgs/Image, best effort) and NS/camera_info (reliable),
 *       built from a binary PGM; --f sets fx = fy, the principal point is the image centre;
 *       frame k is stamped S + k / HZ (default S = 1000)
 *   ros_probe [--domain N] call SERVICE OBJECT TIMEOUT_S [--wait S]
 *       a refgrasp_msgs/srv/Detect client: request header {guid = writer instance handle, seq = 1}
 *   ros_probe [--domain N] pub-twist TOPIC VX WZ [--count K] [--rate HZ]
 *       publishes geometry_msgs/Twist (reliable); prints {"sent":K,"first_to_last_s":T}
 * Exit 0 on success, 1 when nothing arrived in time, 2 on bad arguments or a DDS error. */
#include <dds/dds.h>
#include <dds/ddsi/ddsi_serdata.h>
#include <dds/ddsi/ddsi_sertype.h>
#include <dds/ddsi/q_radmin.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- a sertype that moves raw CDR (encapsulation header included) ---------------------------- */

typedef struct {
  unsigned char *buf; /* encapsulation header + payload */
  uint32_t size;
} raw_sample;

typedef struct {
  struct ddsi_serdata c;
  unsigned char *data;
  uint32_t size;
} raw_serdata;

static raw_serdata *raw_new(const struct ddsi_sertype *tp, enum ddsi_serdata_kind kind, size_t size) {
  raw_serdata *d = calloc(1, sizeof *d);
  ddsi_serdata_init(&d->c, tp, kind);
  d->size = (uint32_t)size;
  d->data = calloc(1, size + 4);
  return d;
}

static bool sd_eqkey(const struct ddsi_serdata *a, const struct ddsi_serdata *b) {
  (void)a; (void)b;
  return true;
}
static uint32_t sd_size(const struct ddsi_serdata *d) { return ((const raw_serdata *)d)->size; }
static void sd_free(struct ddsi_serdata *d) {
  free(((raw_serdata *)d)->data);
  free(d);
}
static struct ddsi_serdata *sd_from_ser(const struct ddsi_sertype *tp, enum ddsi_serdata_kind kind,
                                        const struct nn_rdata *frag, size_t size) {
  raw_serdata *d = raw_new(tp, kind, size);
  uint32_t off = 0;
  while (frag) {
    if (frag->maxp1 > off) {
      const unsigned char *payload = NN_RMSG_PAYLOADOFF(frag->rmsg, NN_RDATA_PAYLOAD_OFF(frag));
      memcpy(d->data + off, payload + off - frag->min, frag->maxp1 - off);
      off = frag->maxp1;
    }
    frag = frag->nextfrag;
  }
  return &d->c;
}
static struct ddsi_serdata *sd_from_ser_iov(const struct ddsi_sertype *tp, enum ddsi_serdata_kind kind,
                                            ddsrt_msg_iovlen_t niov, const ddsrt_iovec_t *iov, size_t size) {
  raw_serdata *d = raw_new(tp, kind, size);
  size_t off = 0;
  for (ddsrt_msg_iovlen_t i = 0; i < niov; i++) {
    memcpy(d->data + off, iov[i].iov_base, iov[i].iov_len);
    off += iov[i].iov_len;
  }
  return &d->c;
}
static struct ddsi_serdata *sd_from_keyhash(const struct ddsi_sertype *tp, const struct ddsi_keyhash *kh) {
  (void)kh;
  return &raw_new(tp, SDK_KEY, 0)->c;
}
static struct ddsi_serdata *sd_from_sample(const struct ddsi_sertype *tp, enum ddsi_serdata_kind kind,
                                           const void *sample) {
  const raw_sample *s = sample;
  const size_t padded = (s->size + 3u) & ~3u; /* as rmw_cyclonedds: a multiple of 4 */
  raw_serdata *d = raw_new(tp, kind, kind == SDK_DATA ? padded : 0);
  if (kind == SDK_DATA) memcpy(d->data, s->buf, s->size);
  return &d->c;
}
static void sd_to_ser(const struct ddsi_serdata *d, size_t off, size_t sz, void *buf) {
  memcpy(buf, ((const raw_serdata *)d)->data + off, sz);
}
static struct ddsi_serdata *sd_to_ser_ref(const struct ddsi_serdata *d, size_t off, size_t sz,
                                          ddsrt_iovec_t *ref) {
  ref->iov_base = ((const raw_serdata *)d)->data + off;
  ref->iov_len = (ddsrt_iov_len_t)sz;
  return ddsi_serdata_ref(d);
}
static void sd_to_ser_unref(struct ddsi_serdata *d, const ddsrt_iovec_t *ref) {
  (void)ref;
  ddsi_serdata_unref(d);
}
static bool sd_to_sample(const struct ddsi_serdata *dcmn, void *sample, void **bufptr, void *buflim) {
  (void)bufptr; (void)buflim;
  const raw_serdata *d = (const raw_serdata *)dcmn;
  raw_sample *s = sample;
  s->size = d->size;
  s->buf = malloc(d->size + 1);
  memcpy(s->buf, d->data, d->size);
  return true;
}
static struct ddsi_serdata *sd_to_untyped(const struct ddsi_serdata *d) {
  raw_serdata *u = raw_new(d->type, SDK_KEY, 0);
  u->c.type = NULL;
  return &u->c;
}
static bool sd_untyped_to_sample(const struct ddsi_sertype *tp, const struct ddsi_serdata *d, void *sample,
                                 void **bufptr, void *buflim) {
  (void)tp; (void)d; (void)bufptr; (void)buflim;
  raw_sample *s = sample;
  s->buf = NULL;
  s->size = 0;
  return true;
}
static size_t sd_print(const struct ddsi_sertype *tp, const struct ddsi_serdata *d, char *buf, size_t n) {
  (void)tp;
  return (size_t)snprintf(buf, n, "raw %u bytes", (unsigned)((const raw_serdata *)d)->size);
}
static void sd_get_keyhash(const struct ddsi_serdata *d, struct ddsi_keyhash *kh, bool force_md5) {
  (void)d; (void)force_md5;
  memset(kh, 0, sizeof *kh);
}

static const struct ddsi_serdata_ops raw_serdata_ops = {
    .eqkey = sd_eqkey, .get_size = sd_size, .from_ser = sd_from_ser, .from_ser_iov = sd_from_ser_iov,
    .from_keyhash = sd_from_keyhash, .from_sample = sd_from_sample, .to_ser = sd_to_ser,
    .to_ser_ref = sd_to_ser_ref, .to_ser_unref = sd_to_ser_unref, .to_sample = sd_to_sample,
    .to_untyped = sd_to_untyped, .untyped_to_sample = sd_untyped_to_sample, .free = sd_free,
    .print = sd_print, .get_keyhash = sd_get_keyhash};

static void st_free(struct ddsi_sertype *tp) {
  ddsi_sertype_fini(tp);
  free(tp);
}
static void st_zero(const struct ddsi_sertype *tp, void *samples, size_t count) {
  (void)tp;
  memset(samples, 0, count * sizeof(raw_sample));
}
static void st_realloc(void **ptrs, const struct ddsi_sertype *tp, void *old, size_t oldcount, size_t count) {
  (void)tp;
  raw_sample *s = realloc(old, count * sizeof(raw_sample));
  if (count > oldcount) memset(s + oldcount, 0, (count - oldcount) * sizeof(raw_sample));
  for (size_t i = 0; i < count; i++) ptrs[i] = &s[i];
}
static void st_free_samples(const struct ddsi_sertype *tp, void **ptrs, size_t count, dds_free_op_t op) {
  (void)tp;
  if (count == 0) return;
  raw_sample *s = ptrs[0];
  if (op & DDS_FREE_CONTENTS_BIT)
    for (size_t i = 0; i < count; i++) {
      free(((raw_sample *)ptrs[i])->buf);
      ((raw_sample *)ptrs[i])->buf = NULL;
    }
  if (op & DDS_FREE_ALL_BIT) free(s);
}
static bool st_equal(const struct ddsi_sertype *a, const struct ddsi_sertype *b) {
  (void)a; (void)b;
  return true;
}
static uint32_t st_hash(const struct ddsi_sertype *tp) {
  (void)tp;
  return 0x52415743u;
}

static const struct ddsi_sertype_ops raw_sertype_ops = {
    .version = ddsi_sertype_v0, .arg = NULL, .free = st_free, .zero_samples = st_zero,
    .realloc_samples = st_realloc, .free_samples = st_free_samples, .equal = st_equal, .hash = st_hash};

/* A topic of `type_name` on `topic`: no type information, XCDR1 only, no key. */
static dds_entity_t raw_topic(dds_entity_t pp, const char *topic, const char *type_name) {
  struct ddsi_sertype *st = calloc(1, sizeof *st);
  ddsi_sertype_init_flags(st, type_name, &raw_sertype_ops, &raw_serdata_ops,
                          DDSI_SERTYPE_FLAG_TOPICKIND_NO_KEY);
  st->allowed_data_representation = DDS_DATA_REPRESENTATION_FLAG_XCDR1;
  return dds_create_topic_sertype(pp, topic, &st, NULL, NULL, NULL);
}

static dds_qos_t *qos(int reliable, int depth, const char *user_data) {
  dds_qos_t *q = dds_create_qos();
  dds_qset_reliability(q, reliable ? DDS_RELIABILITY_RELIABLE : DDS_RELIABILITY_BEST_EFFORT, DDS_INFINITY);
  dds_qset_history(q, DDS_HISTORY_KEEP_LAST, depth);
  dds_qset_writer_data_lifecycle(q, false);
  if (user_data) dds_qset_userdata(q, user_data, strlen(user_data));
  return q;
}

/* ---- CDR (XCDR1, little endian) by hand ------------------------------------------------------- */

typedef struct {
  const unsigned char *p; /* payload, after the 4-byte encapsulation header */
  size_t n, pos;
  int err;
} rd;

static void ralign(rd *r, size_t a) {
  if (r->pos % a) r->pos += a - r->pos % a;
}
static const unsigned char *rtake(rd *r, size_t a, size_t n) {
  ralign(r, a);
  if (r->err || r->pos + n > r->n) {
    r->err = 1;
    return NULL;
  }
  const unsigned char *q = r->p + r->pos;
  r->pos += n;
  return q;
}
static uint32_t ru32(rd *r) {
  const unsigned char *q = rtake(r, 4, 4);
  uint32_t v = 0;
  if (q) memcpy(&v, q, 4);
  return v;
}
static int32_t ri32(rd *r) { return (int32_t)ru32(r); }
static uint8_t ru8(rd *r) {
  const unsigned char *q = rtake(r, 1, 1);
  return q ? *q : 0;
}
static uint64_t ru64(rd *r) {
  const unsigned char *q = rtake(r, 8, 8);
  uint64_t v = 0;
  if (q) memcpy(&v, q, 8);
  return v;
}
static double rf64(rd *r) {
  uint64_t u = ru64(r);
  double d;
  memcpy(&d, &u, 8);
  return d;
}

/* JSON output */
static void jstr(const char *s, size_t n) {
  putchar('"');
  for (size_t i = 0; i < n; i++) {
    unsigned char c = (unsigned char)s[i];
    if (c == '"' || c == '\\') printf("\\%c", c);
    else if (c < 0x20) printf("\\u%04x", c);
    else putchar(c);
  }
  putchar('"');
}
static void jnum(double d) {
  if (isfinite(d)) printf("%.17g", d);
  else printf("null");
}
/* string: uint32 length including the NUL, bytes, NUL */
static void pstr(rd *r, const char *key) {
  uint32_t len = ru32(r);
  const unsigned char *q = len ? rtake(r, 1, len) : NULL;
  if (len == 0 || !q || q[len - 1] != 0) r->err = 1;
  printf("\"%s\":", key);
  if (r->err) printf("null");
  else jstr((const char *)q, len - 1);
}
static void pf64(rd *r, const char *key) {
  printf("\"%s\":", key);
  jnum(rf64(r));
}
static void pu32(rd *r, const char *key) { printf("\"%s\":%u", key, ru32(r)); }
static void pi32(rd *r, const char *key) { printf("\"%s\":%d", key, ri32(r)); }
static void pf64array(rd *r, const char *key, int n) {
  printf("\"%s\":[", key);
  for (int i = 0; i < n; i++) {
    if (i) putchar(',');
    jnum(rf64(r));
  }
  putchar(']');
}
static void pf64seq(rd *r, const char *key) {
  uint32_t n = ru32(r);
  if (n > r->n) r->err = 1;
  pf64array(r, key, r->err ? 0 : (int)n);
}
static void pstrseq(rd *r, const char *key) {
  uint32_t n = ru32(r);
  if (n > r->n) r->err = 1;
  printf("\"%s\":[", key);
  for (uint32_t i = 0; !r->err && i < n; i++) {
    if (i) putchar(',');
    uint32_t len = ru32(r);
    const unsigned char *q = len ? rtake(r, 1, len) : NULL;
    if (len == 0 || !q || q[len - 1] != 0) r->err = 1;
    else jstr((const char *)q, len - 1);
  }
  putchar(']');
}

/* builtin_interfaces/Time {int32 sec, uint32 nanosec}; std_msgs/Header {Time stamp, string frame_id} */
static void pheader(rd *r) {
  printf("\"header\":{\"stamp\":{");
  pi32(r, "sec");
  putchar(',');
  pu32(r, "nanosec");
  printf("},");
  pstr(r, "frame_id");
  putchar('}');
}
static void ppoint(rd *r, const char *key) {
  printf("\"%s\":{", key);
  pf64(r, "x"); putchar(','); pf64(r, "y"); putchar(','); pf64(r, "z");
  putchar('}');
}
static void pquat(rd *r, const char *key) {
  printf("\"%s\":{", key);
  pf64(r, "x"); putchar(','); pf64(r, "y"); putchar(','); pf64(r, "z"); putchar(','); pf64(r, "w");
  putchar('}');
}
/* geometry_msgs/Pose {Point position, Quaternion orientation} */
static void ppose(rd *r, const char *key) {
  printf("\"%s\":{", key);
  ppoint(r, "position");
  putchar(',');
  pquat(r, "orientation");
  putchar('}');
}
/* geometry_msgs/PoseWithCovariance {Pose pose, float64[36] covariance} */
static void pposecov(rd *r, const char *key) {
  printf("\"%s\":{", key);
  ppose(r, "pose");
  putchar(',');
  pf64array(r, "covariance", 36);
  putchar('}');
}
static void ptwist(rd *r, const char *key) {
  printf("\"%s\":{", key);
  ppoint(r, "linear");
  putchar(',');
  ppoint(r, "angular");
  putchar('}');
}

static void dec_image(rd *r) {
  pheader(r); putchar(',');
  pu32(r, "height"); putchar(',');
  pu32(r, "width"); putchar(',');
  pstr(r, "encoding"); putchar(',');
  printf("\"is_bigendian\":%u,", ru8(r));
  pu32(r, "step"); putchar(',');
  uint32_t n = ru32(r);
  const unsigned char *q = rtake(r, 1, n);
  unsigned long long sum = 0;
  for (uint32_t i = 0; q && i < n; i++) sum += q[i];
  printf("\"data_size\":%u,\"data_sum\":%llu", n, sum);
}
static void dec_camera_info(rd *r) {
  pheader(r); putchar(',');
  pu32(r, "height"); putchar(',');
  pu32(r, "width"); putchar(',');
  pstr(r, "distortion_model"); putchar(',');
  pf64seq(r, "d"); putchar(',');
  pf64array(r, "k", 9); putchar(',');
  pf64array(r, "r", 9); putchar(',');
  pf64array(r, "p", 12); putchar(',');
  pu32(r, "binning_x"); putchar(',');
  pu32(r, "binning_y"); putchar(',');
  printf("\"roi\":{");
  pu32(r, "x_offset"); putchar(','); pu32(r, "y_offset"); putchar(',');
  pu32(r, "height"); putchar(','); pu32(r, "width"); putchar(',');
  printf("\"do_rectify\":%u}", ru8(r));
}
static void dec_pose_stamped(rd *r) {
  pheader(r);
  putchar(',');
  ppose(r, "pose");
}
/* vision_msgs 4.x: Detection3DArray {Header header, Detection3D[] detections};
 * Detection3D {Header header, ObjectHypothesisWithPose[] results, BoundingBox3D bbox, string id};
 * ObjectHypothesisWithPose {ObjectHypothesis hypothesis {string class_id, float64 score},
 *                           geometry_msgs/PoseWithCovariance pose};
 * BoundingBox3D {geometry_msgs/Pose center, geometry_msgs/Vector3 size} */
static void dec_detection3d_array(rd *r) {
  pheader(r);
  uint32_t n = ru32(r);
  if (n > r->n) r->err = 1;
  printf(",\"detections\":[");
  for (uint32_t i = 0; !r->err && i < n; i++) {
    if (i) putchar(',');
    putchar('{');
    pheader(r);
    uint32_t m = ru32(r);
    if (m > r->n) r->err = 1;
    printf(",\"results\":[");
    for (uint32_t k = 0; !r->err && k < m; k++) {
      if (k) putchar(',');
      printf("{\"hypothesis\":{");
      pstr(r, "class_id"); putchar(','); pf64(r, "score");
      printf("},");
      pposecov(r, "pose");
      putchar('}');
    }
    printf("],\"bbox\":{");
    ppose(r, "center");
    putchar(',');
    ppoint(r, "size");
    printf("},");
    pstr(r, "id");
    putchar('}');
  }
  putchar(']');
}
/* refgrasp_msgs/ObjectInfo {Header header, string object_name, bool found, float64[9] rotation,
 * float64[3] translation, int32 inliers} */
static void dec_object_info(rd *r) {
  pheader(r); putchar(',');
  pstr(r, "object_name"); putchar(',');
  printf("\"found\":%s,", ru8(r) ? "true" : "false");
  pf64array(r, "rotation", 9); putchar(',');
  pf64array(r, "translation", 3); putchar(',');
  pi32(r, "inliers");
}
/* refgrasp_msgs/ObjectCorners {Header header, string object_name, bool found, bool tracked,
 * float64[8] corners, float64[9] homography, int32 inliers} */
static void dec_object_corners(rd *r) {
  pheader(r); putchar(',');
  pstr(r, "object_name"); putchar(',');
  printf("\"found\":%s,", ru8(r) ? "true" : "false");
  printf("\"tracked\":%s,", ru8(r) ? "true" : "false");
  pf64array(r, "corners", 8); putchar(',');
  pf64array(r, "homography", 9); putchar(',');
  pi32(r, "inliers");
}
static void dec_joint_state(rd *r) {
  pheader(r); putchar(',');
  pstrseq(r, "name"); putchar(',');
  pf64seq(r, "position"); putchar(',');
  pf64seq(r, "velocity"); putchar(',');
  pf64seq(r, "effort");
}
static void dec_odometry(rd *r) {
  pheader(r); putchar(',');
  pstr(r, "child_frame_id"); putchar(',');
  pposecov(r, "pose");
  printf(",\"twist\":{");
  ptwist(r, "twist");
  putchar(',');
  pf64array(r, "covariance", 36);
  putchar('}');
}
static void dec_twist(rd *r) {
  ppoint(r, "linear");
  putchar(',');
  ppoint(r, "angular");
}
/* JointTrajectory {Header header, string[] joint_names, JointTrajectoryPoint[] points};
 * JointTrajectoryPoint {float64[] positions, velocities, accelerations, effort,
 *                       builtin_interfaces/Duration time_from_start} */
static void dec_joint_trajectory(rd *r) {
  pheader(r); putchar(',');
  pstrseq(r, "joint_names");
  uint32_t n = ru32(r);
  if (n > r->n) r->err = 1;
  printf(",\"points\":[");
  for (uint32_t i = 0; !r->err && i < n; i++) {
    if (i) putchar(',');
    putchar('{');
    pf64seq(r, "positions"); putchar(',');
    pf64seq(r, "velocities"); putchar(',');
    pf64seq(r, "accelerations"); putchar(',');
    pf64seq(r, "effort");
    printf(",\"time_from_start\":{");
    pi32(r, "sec"); putchar(','); pu32(r, "nanosec");
    printf("}}");
  }
  putchar(']');
}
/* rmw_cyclonedds request header {uint64 guid, int64 seq} in front of the service fields */
static void prequest_header(rd *r) {
  uint64_t guid = ru64(r);
  int64_t seq = (int64_t)ru64(r);
  printf("\"request_header\":{\"guid\":%llu,\"seq\":%lld}", (unsigned long long)guid, (long long)seq);
}
/* refgrasp_msgs/srv/Detect response {bool found, float64[9] rotation, float64[3] translation, string error} */
static void dec_detect_response(rd *r) {
  prequest_header(r);
  printf(",\"found\":%s,", ru8(r) ? "true" : "false");
  pf64array(r, "rotation", 9); putchar(',');
  pf64array(r, "translation", 3); putchar(',');
  pstr(r, "error");
}
static void dec_detect_request(rd *r) {
  prequest_header(r); putchar(',');
  pstr(r, "object_name"); putchar(',');
  pf64(r, "timeout_s");
}

typedef void (*decoder)(rd *);
static const struct {
  const char *type;
  decoder dec;
} decoders[] = {
    {"sensor_msgs::msg::dds_::Image_", dec_image},
    {"sensor_msgs::msg::dds_::CameraInfo_", dec_camera_info},
    {"sensor_msgs::msg::dds_::JointState_", dec_joint_state},
    {"geometry_msgs::msg::dds_::PoseStamped_", dec_pose_stamped},
    {"geometry_msgs::msg::dds_::Twist_", dec_twist},
    {"vision_msgs::msg::dds_::Detection3DArray_", dec_detection3d_array},
    {"nav_msgs::msg::dds_::Odometry_", dec_odometry},
    {"trajectory_msgs::msg::dds_::JointTrajectory_", dec_joint_trajectory},
    {"refgrasp_msgs::msg::dds_::ObjectInfo_", dec_object_info},
    {"refgrasp_msgs::msg::dds_::ObjectCorners_", dec_object_corners},
    {"refgrasp_msgs::srv::dds_::Detect_Response_", dec_detect_response},
    {"refgrasp_msgs::srv::dds_::Detect_Request_", dec_detect_request},
};

/* Prints one sample as a JSON line. */
static void print_sample(const char *type, const raw_sample *s) {
  const char *enc = "?";
  if (s->size >= 4) {
    if (s->buf[0] == 0 && s->buf[1] == 1) enc = "CDR_LE";
    else if (s->buf[0] == 0 && s->buf[1] == 0) enc = "CDR_BE";
    else if (s->buf[0] == 0 && (s->buf[1] == 6 || s->buf[1] == 7 || s->buf[1] == 8 || s->buf[1] == 9 ||
                                s->buf[1] == 10 || s->buf[1] == 11))
      enc = "XCDR2";
  }
  printf("{\"encapsulation\":\"%s\",\"size\":%u,\"msg\":{", enc, s->size);
  rd r = {s->size >= 4 ? s->buf + 4 : s->buf, s->size >= 4 ? s->size - 4 : 0, 0, strcmp(enc, "CDR_LE") != 0};
  int known = 0;
  for (size_t i = 0; i < sizeof decoders / sizeof decoders[0]; i++)
    if (strcmp(decoders[i].type, type) == 0) {
      if (!r.err) decoders[i].dec(&r);
      known = 1;
    }
  /* the payload is padded to a multiple of 4: at most 3 bytes may be left */
  const size_t left = r.n - r.pos;
  printf("},\"ok\":%s,\"left_over\":%zu}\n", known && !r.err && left < 4 ? "true" : "false", r.err ? 0 : left);
  fflush(stdout);
}

/* ---- CDR writer --------------------------------------------------------------------------------- */

typedef struct {
  unsigned char *b;
  size_t n, cap;
} wr;

static void wreserve(wr *w, size_t more) {
  if (w->n + more > w->cap) {
    w->cap = (w->n + more) * 2;
    w->b = realloc(w->b, w->cap);
  }
}
static void wput(wr *w, size_t align, const void *p, size_t n) {
  /* alignment is relative to the payload, which starts after the 4-byte header */
  while ((w->n - 4) % align) {
    wreserve(w, 1);
    w->b[w->n++] = 0;
  }
  wreserve(w, n);
  memcpy(w->b + w->n, p, n);
  w->n += n;
}
static void wu32(wr *w, uint32_t v) { wput(w, 4, &v, 4); }
static void wi32(wr *w, int32_t v) { wput(w, 4, &v, 4); }
static void wu8(wr *w, uint8_t v) { wput(w, 1, &v, 1); }
static void wu64(wr *w, uint64_t v) { wput(w, 8, &v, 8); }
static void wf64(wr *w, double v) { wput(w, 8, &v, 8); }
static void wstr(wr *w, const char *s) {
  uint32_t len = (uint32_t)strlen(s) + 1;
  wu32(w, len);
  wput(w, 1, s, len);
}
static wr wbegin(void) {
  wr w = {malloc(64), 0, 64};
  const unsigned char hdr[4] = {0x00, 0x01, 0x00, 0x00}; /* CDR_LE, options 0 */
  memcpy(w.b, hdr, 4);
  w.n = 4;
  return w;
}
static void wheader(wr *w, int32_t sec, uint32_t nsec, const char *frame) {
  wi32(w, sec);
  wu32(w, nsec);
  wstr(w, frame);
}

/* ---- commands ------------------------------------------------------------------------------------ */

static double now_s(void) { return (double)dds_time() * 1e-9; }

/* Waits up to timeout_s for a writer to match a reader. */
static int wait_matched(dds_entity_t writer, double timeout_s) {
  const double end = now_s() + timeout_s;
  dds_publication_matched_status_t st;
  do {
    dds_get_publication_matched_status(writer, &st);
    if (st.current_count > 0) return 1;
    dds_sleepfor(DDS_MSECS(10));
  } while (now_s() < end);
  return 0;
}

static int cmd_list(dds_entity_t pp, double wait_s) {
  dds_guid_t self;
  dds_get_guid(pp, &self);
  dds_entity_t rp = dds_create_reader(pp, DDS_BUILTIN_TOPIC_DCPSPUBLICATION, NULL, NULL);
  dds_entity_t rs = dds_create_reader(pp, DDS_BUILTIN_TOPIC_DCPSSUBSCRIPTION, NULL, NULL);
  if (rp < 0 || rs < 0) return 2;
  dds_sleepfor(DDS_SECS(0) + (dds_duration_t)(wait_s * 1e9));
  int n_total = 0;
  for (int k = 0; k < 2; k++) {
    dds_entity_t rdr = k == 0 ? rp : rs;
    void *samples[64] = {NULL};
    dds_sample_info_t info[64];
    int n;
    while ((n = dds_take(rdr, samples, info, 64, 64)) > 0) {
      for (int i = 0; i < n; i++) {
        const dds_builtintopic_endpoint_t *e = samples[i];
        if (!info[i].valid_data || memcmp(e->participant_key.v, self.v, 12) == 0) continue;
        if (strncmp(e->topic_name, "DCPS", 4) == 0) continue;
        printf("%s %s %s\n", k == 0 ? "pub" : "sub", e->topic_name, e->type_name);
        n_total++;
      }
      dds_return_loan(rdr, samples, n);
    }
  }
  fflush(stdout);
  return n_total > 0 ? 0 : 1;
}

static int cmd_echo(dds_entity_t pp, const char *topic, const char *type, int count, double timeout_s) {
  dds_entity_t tp = raw_topic(pp, topic, type);
  if (tp < 0) {
    fprintf(stderr, "ros_probe: topic %s: %s\n", topic, dds_strretcode(tp));
    return 2;
  }
  dds_qos_t *q = qos(0, 10, NULL);
  dds_entity_t r = dds_create_reader(pp, tp, q, NULL);
  dds_delete_qos(q);
  if (r < 0) return 2;
  int got = 0;
  const double end = now_s() + timeout_s;
  while (got < count && now_s() < end) {
    raw_sample s = {NULL, 0};
    void *ptr = &s;
    dds_sample_info_t info;
    if (dds_take(r, &ptr, &info, 1, 1) == 1) {
      if (info.valid_data) {
        print_sample(type, &s);
        got++;
      }
      free(s.buf);
    } else {
      dds_sleepfor(DDS_MSECS(2));
    }
  }
  return got >= count ? 0 : 1;
}

static unsigned char *read_pgm(const char *path, int *w, int *h) {
  FILE *f = fopen(path, "rb");
  if (!f) return NULL;
  int maxv = 0;
  if (fscanf(f, "P5 %d %d %d", w, h, &maxv) != 3 || maxv != 255 || *w <= 0 || *h <= 0) {
    fclose(f);
    return NULL;
  }
  fgetc(f);
  unsigned char *p = malloc((size_t)*w * (size_t)*h);
  size_t got = fread(p, 1, (size_t)*w * (size_t)*h, f);
  fclose(f);
  if (got != (size_t)*w * (size_t)*h) {
    free(p);
    return NULL;
  }
  return p;
}

static int write_raw(dds_entity_t writer, wr *w) {
  raw_sample s = {w->b, (uint32_t)w->n};
  return dds_write(writer, &s) < 0 ? 2 : 0;
}

static int cmd_pub_image(dds_entity_t pp, const char *ns, const char *pgm, const char *encoding,
                         const char *frame, double f, int count, double rate, double stamp0) {
  int w = 0, h = 0;
  unsigned char *gray = read_pgm(pgm, &w, &h);
  if (!gray) {
    fprintf(stderr, "ros_probe: %s: not a binary 8-bit PGM\n", pgm);
    return 2;
  }
  int channels = 1;
  if (!strcmp(encoding, "rgb8") || !strcmp(encoding, "bgr8")) channels = 3;
  char t_img[256], t_info[256];
  snprintf(t_img, sizeof t_img, "rt%s/image_raw", ns);
  snprintf(t_info, sizeof t_info, "rt%s/camera_info", ns);
  dds_entity_t ti = raw_topic(pp, t_img, "sensor_msgs::msg::dds_::Image_");
  dds_entity_t tc = raw_topic(pp, t_info, "sensor_msgs::msg::dds_::CameraInfo_");
  dds_qos_t *qi = qos(0, 1, NULL), *qc = qos(1, 1, NULL);
  dds_entity_t wi = dds_create_writer(pp, ti, qi, NULL), wc = dds_create_writer(pp, tc, qc, NULL);
  dds_delete_qos(qi);
  dds_delete_qos(qc);
  if (ti < 0 || tc < 0 || wi < 0 || wc < 0) return 2;
  if (!wait_matched(wi, 10)) return 1;
  dds_sleepfor(DDS_MSECS(200));
  for (int k = 0; k < count; k++) {
    const double t = stamp0 + k / rate;
    const int32_t sec = (int32_t)floor(t);
    const uint32_t nsec = (uint32_t)llround((t - sec) * 1e9);
    /* sensor_msgs/CameraInfo */
    wr c = wbegin();
    wheader(&c, sec, nsec, frame);
    wu32(&c, (uint32_t)h);
    wu32(&c, (uint32_t)w);
    wstr(&c, "plumb_bob");
    wu32(&c, 5);
    for (int i = 0; i < 5; i++) wf64(&c, 0.0);
    const double K[9] = {f, 0, (w - 1) / 2.0, 0, f, (h - 1) / 2.0, 0, 0, 1};
    const double R[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    const double P[12] = {f, 0, (w - 1) / 2.0, 0, 0, f, (h - 1) / 2.0, 0, 0, 0, 1, 0};
    for (int i = 0; i < 9; i++) wf64(&c, K[i]);
    for (int i = 0; i < 9; i++) wf64(&c, R[i]);
    for (int i = 0; i < 12; i++) wf64(&c, P[i]);
    wu32(&c, 0);
    wu32(&c, 0);
    wu32(&c, 0); wu32(&c, 0); wu32(&c, 0); wu32(&c, 0); wu8(&c, 0);
    int rc = write_raw(wc, &c);
    free(c.b);
    /* sensor_msgs/Image */
    wr m = wbegin();
    wheader(&m, sec, nsec, frame);
    wu32(&m, (uint32_t)h);
    wu32(&m, (uint32_t)w);
    wstr(&m, encoding);
    wu8(&m, 0);
    wu32(&m, (uint32_t)(w * channels));
    const size_t n = (size_t)w * (size_t)h * (size_t)channels;
    wu32(&m, (uint32_t)n);
    wreserve(&m, n);
    for (size_t i = 0; i < (size_t)w * (size_t)h; i++)
      for (int ch = 0; ch < channels; ch++) m.b[m.n++] = gray[i];
    rc |= write_raw(wi, &m);
    free(m.b);
    if (rc) return 2;
    dds_sleepfor((dds_duration_t)(1e9 / rate));
  }
  free(gray);
  dds_sleepfor(DDS_MSECS(200));
  return 0;
}

static int cmd_call(dds_entity_t pp, const char *service, const char *object, double timeout_s, double wait_s) {
  char treq[256], trep[256];
  snprintf(treq, sizeof treq, "rq%sRequest", service);
  snprintf(trep, sizeof trep, "rr%sReply", service);
  dds_entity_t tq = raw_topic(pp, treq, "refgrasp_msgs::srv::dds_::Detect_Request_");
  dds_entity_t tr = raw_topic(pp, trep, "refgrasp_msgs::srv::dds_::Detect_Response_");
  dds_qos_t *q = qos(1, 10, "clientid=01.0f.ee.ee.00.00.00.00.00.00.00.00.00.00.00.01;");
  dds_entity_t w = dds_create_writer(pp, tq, q, NULL), r = dds_create_reader(pp, tr, q, NULL);
  dds_delete_qos(q);
  if (tq < 0 || tr < 0 || w < 0 || r < 0) return 2;
  const double end = now_s() + wait_s;
  for (;;) { /* rmw_service_server_is_available */
    dds_publication_matched_status_t ps;
    dds_subscription_matched_status_t ss;
    dds_get_publication_matched_status(w, &ps);
    dds_get_subscription_matched_status(r, &ss);
    if (ps.current_count > 0 && ss.current_count > 0) break;
    if (now_s() > end) return 1;
    dds_sleepfor(DDS_MSECS(10));
  }
  dds_instance_handle_t guid = 0;
  dds_get_instance_handle(w, &guid);
  const int64_t seq = 1;
  wr m = wbegin();
  wu64(&m, guid);
  wu64(&m, (uint64_t)seq);
  wstr(&m, object);
  wf64(&m, timeout_s);
  int rc = write_raw(w, &m);
  free(m.b);
  if (rc) return 2;
  while (now_s() < end + timeout_s) {
    raw_sample s = {NULL, 0};
    void *ptr = &s;
    dds_sample_info_t info;
    if (dds_take(r, &ptr, &info, 1, 1) == 1) {
      uint64_t g = 0;
      int64_t sq = 0;
      if (info.valid_data && s.size >= 20) {
        memcpy(&g, s.buf + 4, 8);
        memcpy(&sq, s.buf + 12, 8);
      }
      if (info.valid_data && g == guid && sq == seq) {
        print_sample("refgrasp_msgs::srv::dds_::Detect_Response_", &s);
        free(s.buf);
        return 0;
      }
      free(s.buf);
    } else {
      dds_sleepfor(DDS_MSECS(2));
    }
  }
  return 1;
}

static int cmd_pub_twist(dds_entity_t pp, const char *topic, double vx, double wz, int count, double rate) {
  dds_entity_t tp = raw_topic(pp, topic, "geometry_msgs::msg::dds_::Twist_");
  dds_qos_t *q = qos(1, 1, NULL);
  dds_entity_t w = dds_create_writer(pp, tp, q, NULL);
  dds_delete_qos(q);
  if (tp < 0 || w < 0) return 2;
  if (!wait_matched(w, 10)) return 1;
  double first = 0, last = 0;
  for (int k = 0; k < count; k++) {
    wr m = wbegin();
    wf64(&m, vx); wf64(&m, 0); wf64(&m, 0);
    wf64(&m, 0); wf64(&m, 0); wf64(&m, wz);
    int rc = write_raw(w, &m);
    free(m.b);
    if (rc) return 2;
    last = now_s();
    if (k == 0) first = last;
    if (k + 1 < count) dds_sleepfor((dds_duration_t)(1e9 / rate));
  }
  /* how long the commands really spanned (a loaded machine stretches the sleeps) */
  printf("{\"sent\":%d,\"first_to_last_s\":%.6f}\n", count, last - first);
  return 0;
}

static double optd(int argc, char **argv, const char *name, double def) {
  for (int i = 0; i + 1 < argc; i++)
    if (!strcmp(argv[i], name)) return atof(argv[i + 1]);
  return def;
}
static const char *opts(int argc, char **argv, const char *name, const char *def) {
  for (int i = 0; i + 1 < argc; i++)
    if (!strcmp(argv[i], name)) return argv[i + 1];
  return def;
}

int main(int argc, char **argv) {
  int a = 1;
  int domain = 0;
  if (a + 1 < argc && !strcmp(argv[a], "--domain")) {
    domain = atoi(argv[a + 1]);
    a += 2;
  }
  if (a >= argc) {
    fprintf(stderr, "usage: ros_probe [--domain N] list|echo|pub-image|call|pub-twist ...\n");
    return 2;
  }
  const char *cmd = argv[a++];
  dds_entity_t pp = dds_create_participant((dds_domainid_t)domain, NULL, NULL);
  if (pp < 0) {
    fprintf(stderr, "ros_probe: participant: %s\n", dds_strretcode(pp));
    return 2;
  }
  int rc = 2;
  if (!strcmp(cmd, "list")) {
    rc = cmd_list(pp, optd(argc, argv, "--wait", 2.0));
  } else if (!strcmp(cmd, "echo") && a + 1 < argc) {
    rc = cmd_echo(pp, argv[a], argv[a + 1], (int)optd(argc, argv, "--count", 1),
                  optd(argc, argv, "--timeout", 10));
  } else if (!strcmp(cmd, "pub-image") && a + 2 < argc) {
    rc = cmd_pub_image(pp, argv[a], argv[a + 1], argv[a + 2], opts(argc, argv, "--frame", "camera_optical_frame"),
                       optd(argc, argv, "--f", 550), (int)optd(argc, argv, "--count", 1),
                       optd(argc, argv, "--rate", 5), optd(argc, argv, "--stamp0", 1000));
  } else if (!strcmp(cmd, "call") && a + 2 < argc) {
    rc = cmd_call(pp, argv[a], argv[a + 1], atof(argv[a + 2]), optd(argc, argv, "--wait", 10));
  } else if (!strcmp(cmd, "pub-twist") && a + 2 < argc) {
    rc = cmd_pub_twist(pp, argv[a], atof(argv[a + 1]), atof(argv[a + 2]), (int)optd(argc, argv, "--count", 10),
                       optd(argc, argv, "--rate", 20));
  } else {
    fprintf(stderr, "ros_probe: bad arguments for '%s'\n", cmd);
  }
  dds_delete(pp);
  return rc;
}
