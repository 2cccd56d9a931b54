// Decodes files that each hold one encoded LCM message the way lcm-spy does:
// lcm-spy's type database (lcm.spy.LCMTypeDatabase, which scans the class path
// for LCM types) resolves the fingerprint in the first 8 bytes to a class, and
// the class's byte[] constructor decodes the message. Prints, per file i,
// "i class=<name>" and "i <field>=<value>" for every public field (nested
// messages as "<field>.<subfield>", arrays of more than 8 values by length), so
// the C++ test that encoded the files can compare. Run with Java's
// single-file source launcher:
//   java -cp lcm.jar:ag_lcmtypes.jar SpyDecodeCheck.java FILE...

import java.io.ByteArrayInputStream;
import java.io.DataInputStream;
import java.lang.reflect.Array;
import java.lang.reflect.Field;
import java.lang.reflect.Modifier;
import java.nio.file.Files;
import java.nio.file.Paths;
import lcm.spy.LCMTypeDatabase;

public class SpyDecodeCheck {
  public static void main(String[] args) throws Exception {
    LCMTypeDatabase database = new LCMTypeDatabase();
    for (int i = 0; i < args.length; i++) {
      byte[] buf = Files.readAllBytes(Paths.get(args[i]));
      long fingerprint = new DataInputStream(new ByteArrayInputStream(buf)).readLong();
      Class<?> cls = database.getClassByFingerprint(fingerprint);
      if (cls == null) {
        System.out.println(i + " class=UNKNOWN");
        continue;
      }
      System.out.println(i + " class=" + cls.getName());
      Object msg = cls.getConstructor(byte[].class).newInstance((Object) buf);
      print(i + " ", "", msg);
    }
  }

  private static void print(String line, String prefix, Object msg) throws Exception {
    for (Field field : msg.getClass().getFields()) {
      if (Modifier.isStatic(field.getModifiers())) continue;
      Object value = field.get(msg);
      String name = prefix + field.getName();
      if (value != null && value.getClass().isArray()) {
        int length = Array.getLength(value);
        if (length > 8 || value.getClass().getComponentType().isArray()) {
          System.out.println(line + name + ".length=" + length);
        } else {
          StringBuilder text = new StringBuilder("[");
          for (int k = 0; k < length; k++) text.append(k > 0 ? ", " : "").append(Array.get(value, k));
          System.out.println(line + name + "=" + text.append("]"));
        }
      } else if (value instanceof lcm.lcm.LCMEncodable) {
        print(line, name + ".", value);
      } else {
        System.out.println(line + name + "=" + value);
      }
    }
  }
}
